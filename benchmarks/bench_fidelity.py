"""Fidelity: how closely `kinetre animate` on an unrigged mesh follows the artist's own rig.

For each public rigged avatar in ../shared/data/avatars and each of its animations:

1. the avatar's body is posed at the clip's first frame by the independent glTF player
   (tests/export/gltf_player.py: pygltflib + numpy, no Kinetre; the measures are tests/export/fidelity.py,
   shared with the tests) and written as an unrigged PLY;
2. `kinetre animate MESH.ply --motion AVATAR.glb#CLIP -o out.glb` runs with the defaults (the CLI's own
   `main`, in this process);
3. out.glb is posed by the same player at its frames and compared vertex by vertex with the avatar's own
   skin at the same clip times. The loader welds vertices by position, so every written vertex is matched
   to the output vertex at its rest position (exact: the residual is printed as `match_pct`).

Errors are distances in % of the character's height (the rest pose's extent along +Y). Per clip:
`mean_pct` over every vertex of the compared frames, `p95_pct`, `max_pct`, `worst_frame_pct` (the worst
frame's mean) and `still_mean_pct` / `still_worst_frame_pct`, the same for the frame-0 pose held still
(a method that does no better than that has not followed the motion). At most `--frames` frames per clip
(evenly spaced, first and last included) are compared; `frames` / `frames_total` say how many.

Methods (the `method` field):

* `animate`: the CLI's default path above; targets on humanoids: mean ≤ 1.2 % (Robot_Dance ≤ 2.5 %),
  p95 ≤ 5 %, worst frame ≤ 3 %, and better than standing still (`within_target`);
* `avatar`: `kinetre avatar AVATAR.glb --motion AVATAR.glb#CLIP -o out.glb`, the avatar driven by its own
  animation through the Kinect-20 retarget; target mean ≤ 1 %;
* `nearest_bone`: reference, each vertex rigidly follows the artist bone nearest to it at frame 0 (a bone
  runs from a joint to each child joint and moves with the joint; a childless joint is a point bone);
* `blender_auto`: reference, Blender's one-click automatic weights (bone heat) where `blender` is on PATH:
  the avatar imported by Blender's glTF importer, its skin removed, the meshes parented to the armature
  with ARMATURE_AUTO, compared with Blender's own evaluation of the artist skin (`reference_check_pct`:
  Blender's artist skin against the player's, the mean over the compared frames).

Besides the public avatars, two synthetic characters with a known walk (tests/rigs.py) stand for the rigs
the public set lacks: a chibi game rig (`chibi`: root on the floor, hands straight off the chest, sockets)
and an eight-legged creature (`spider`); `--avatar chibi` or `--avatar spider` runs one of them.

One avatar and clip from the command line, for quick iteration:
    python benchmarks/bench_fidelity.py --avatar ../shared/data/avatars/CesiumMan.glb --anim 0 --frames 20
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from export.fidelity import Clip, errors, figures  # noqa: E402  (the independent player's measures)
from export.gltf_player import GltfFile  # noqa: E402
import rigs  # noqa: E402  (synthetic rigs with a known walk)

DATA = HERE.parent / ".." / "shared" / "data"
AVATARS = {"robot_quaternius": "humanoid", "CesiumMan": "humanoid", "RiggedFigure": "humanoid",
           "Fox": "quadruped"}
SYNTHETIC = {"chibi": ("humanoid", lambda: rigs.chibi(40)), "spider": ("other", lambda: rigs.legged_creature(8, 40))}
FRAMES = 30               # compared frames per clip
TARGETS = {"mean_pct": 1.2, "p95_pct": 5.0, "worst_frame_pct": 3.0}
CLIP_MEAN_TARGET = {"Robot_Dance": 2.5}
AVATAR_MEAN_TARGET = 1.0
BLENDER_SCRIPT = HERE / "blender_auto_weights.py"


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """`kinetre ARGV` through the CLI's own entry point, in this process: (status, stdout, stderr)."""
    from kinetre.cli import main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


def row(clip: Clip, kind: str, method: str, **fields) -> dict:
    return {"bench": "fidelity", "avatar": clip.path.stem, "clip": clip.name, "kind": kind, "method": method,
            "frames": len(clip.index), "frames_total": clip.total, "vertices": clip.player.vertex_count, **fields}


def messages(stderr: str) -> str:
    return " | ".join(line.split("kinetre: ", 1)[-1] for line in stderr.splitlines() if line.strip())


def animate_row(clip: Clip, kind: str, work: Path, extra: list[str]) -> dict:
    mesh = clip.write_mesh(work / "mesh.ply")
    out = work / "animate.glb"
    t0 = time.perf_counter()
    status, _, stderr = run_cli(["animate", str(mesh), "--motion", f"{clip.path}#{clip.anim}", "-o", str(out),
                                 "-q", *extra])
    fields = {"skeleton": skeleton_of(clip), "seconds": round(time.perf_counter() - t0, 2)}
    if extra:
        fields["args"] = " ".join(extra)
    if status != 0:
        return row(clip, kind, "animate", **fields, error=messages(stderr), within_target=False)
    got, gap = clip.compare_mesh_animation(out)
    fields.update(got, match_pct=round(gap, 6))
    if kind == "humanoid":
        target = {**TARGETS, "mean_pct": CLIP_MEAN_TARGET.get(clip.name, TARGETS["mean_pct"])}
        fields.update({f"target_{k}": v for k, v in target.items()})
        fields["within_target"] = all(got[k] <= v for k, v in target.items()) and got["beats_still"]
    else:
        fields["within_target"] = got["beats_still"]
    if stderr.strip():
        fields["notes"] = messages(stderr)
    return row(clip, kind, "animate", **fields)


def avatar_row(clip: Clip, kind: str, work: Path) -> dict:
    out = work / "avatar.glb"
    status, _, stderr = run_cli(["avatar", str(clip.path), "--motion", f"{clip.path}#{clip.anim}", "-o", str(out),
                                 "-q"])
    if status != 0:
        return row(clip, kind, "avatar", error=messages(stderr), within_target=False)
    got = clip.compare_avatar_animation(out)
    return row(clip, kind, "avatar", **got, target_mean_pct=AVATAR_MEAN_TARGET,
               within_target=got["mean_pct"] <= AVATAR_MEAN_TARGET)


def skeleton_of(clip: Clip) -> str:
    """The skeleton Kinetre reads the clip as (kinect20: the person path; otherwise the shape fit)."""
    import kinetre
    from kinetre.errors import KinetreError
    try:
        return kinetre.load_take(f"{clip.path}#{clip.anim}").model.name
    except KinetreError:  # a refused clip: the animate row carries the message
        return "refused"


def blender_rows(clips: list[Clip], kind: str, work: Path) -> list[dict]:
    """Blender's automatic weights on one avatar's clips (one Blender run), or [] without Blender."""
    if shutil.which("blender") is None or not clips:
        return []
    from scipy.spatial import cKDTree
    job = {"path": str(clips[0].path.resolve()), "fps": 30.0,
           "clips": [{"animation": clip.player.animation_index(clip.anim), "name": clip.name,
                      "times": [float(t) for t in clip.times]} for clip in clips]}
    (work / "job.json").write_text(json.dumps(job))
    out = work / "blender.npz"
    done = subprocess.run(["blender", "-b", "--factory-startup", "--python", str(BLENDER_SCRIPT), "--",
                           str(work / "job.json"), str(out)], capture_output=True, text=True, timeout=1800)
    if done.returncode != 0 or not out.exists():
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
        return [row(clip, kind, "blender_auto", error=f"blender failed: {tail[0]}") for clip in clips]
    got = np.load(out)
    heat_failed = "failed to find solution" in done.stdout   # Blender's bone-heat warning
    rows = []
    for k, clip in enumerate(clips):
        artist, auto = got[f"artist_{k}"], got[f"auto_{k}"]
        still = errors(artist[:1], artist, clip.height)
        # Blender's artist skin against the player's: vertices matched by position at the first frame
        idx = cKDTree(artist[0]).query(clip.reference[0])[1]
        check = errors(artist[:, idx], clip.reference, clip.height).mean()
        rows.append(row(clip, kind, "blender_auto", **figures(errors(auto, artist, clip.height), still),
                        reference_check_pct=round(float(check), 4), heat_failed_on_some_bones=heat_failed))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--avatar", help="one rigged .glb, or chibi / spider (default: every public avatar and both "
                                     "synthetic ones)")
    ap.add_argument("--anim", action="append", help="animation name or index (repeatable; default: every one)")
    ap.add_argument("--kind", default=None, choices=("humanoid", "quadruped", "other"),
                    help="what --avatar is (default: humanoid)")
    ap.add_argument("--frames", type=int, default=FRAMES, help=f"compared frames per clip (default {FRAMES})")
    ap.add_argument("--methods", default="animate,avatar,nearest_bone,blender_auto",
                    help="comma-separated subset of animate, avatar, nearest_bone, blender_auto")
    ap.add_argument("--animate-args", default="", help="extra `kinetre animate` arguments, e.g. '--nodes 256'")
    args = ap.parse_args()
    methods = set(args.methods.split(","))
    todo = [(name, kind) for name, (kind, _) in SYNTHETIC.items() if name == args.avatar] if args.avatar in SYNTHETIC \
        else [(Path(args.avatar), args.kind or "humanoid")] if args.avatar else \
        [(DATA / "avatars" / f"{name}.glb", kind) for name, kind in AVATARS.items()] + \
        [(name, kind) for name, (kind, _) in SYNTHETIC.items()]
    with tempfile.TemporaryDirectory(prefix="kinetre-fidelity-") as tmp:
        work = Path(tmp)
        for path, kind in todo:
            if path in SYNTHETIC:
                rigs.write_glb(SYNTHETIC[path][1](), work / f"{path}.glb")
                path = work / f"{path}.glb"
            player = GltfFile(path)
            names = args.anim or [a.name or str(i) for i, a in enumerate(player.doc.animations)]
            clips = [Clip(player, anim, args.frames) for anim in names]
            for clip in clips:
                if "animate" in methods:
                    print(json.dumps(animate_row(clip, kind, work, args.animate_args.split())), flush=True)
                if "avatar" in methods and kind == "humanoid":
                    print(json.dumps(avatar_row(clip, kind, work)), flush=True)
                if "nearest_bone" in methods:
                    print(json.dumps(row(clip, kind, "nearest_bone", **clip.nearest_bone())), flush=True)
            if "blender_auto" in methods:
                for line in blender_rows(clips, kind, work):
                    print(json.dumps(line), flush=True)
    if "blender_auto" in methods and shutil.which("blender") is None:
        print("bench_fidelity: blender is not on PATH: no blender_auto rows", file=sys.stderr)


if __name__ == "__main__":
    main()
