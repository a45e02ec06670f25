"""Fidelity: how closely `kinetre animate` on an unrigged mesh follows the artist's own rig.

For each public rigged avatar in ../shared/data/avatars and each of its animations:

1. the avatar's body is posed at the clip's first frame by the independent glTF player
   (tests/export/gltf_player.py: pygltflib + numpy, no Kinetre) and written as an unrigged PLY;
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

One avatar and clip from the command line, for quick iteration:
    python benchmarks/bench_fidelity.py --avatar ../shared/data/avatars/CesiumMan.glb --anim 0 --frames 20
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "export"))
from gltf_player import GltfFile  # noqa: E402  (the independent player, shared with the tests)

DATA = HERE.parent / ".." / "shared" / "data"
AVATARS = {"robot_quaternius": "humanoid", "CesiumMan": "humanoid", "RiggedFigure": "humanoid",
           "Fox": "quadruped"}
FRAMES = 30               # compared frames per clip
TARGETS = {"mean_pct": 1.2, "p95_pct": 5.0, "worst_frame_pct": 3.0}
CLIP_MEAN_TARGET = {"Robot_Dance": 2.5}
AVATAR_MEAN_TARGET = 1.0
BLENDER_SCRIPT = HERE / "blender_auto_weights.py"


def height_of(player: GltfFile) -> float:
    """The character's height: the rest pose's extent along +Y."""
    return float(np.ptp(player.vertices(0.0, None)[:, 1]))


def compared_frames(total: int, most: int) -> np.ndarray:
    return np.unique(np.round(np.linspace(0, total - 1, min(total, most))).astype(int))


def errors(posed: np.ndarray, reference: np.ndarray, height: float) -> np.ndarray:
    """(F, V) distances in % of height."""
    return 100.0 * np.linalg.norm(posed - reference, axis=2) / height


def figures(err: np.ndarray, still: np.ndarray) -> dict:
    per_frame = err.mean(axis=1)
    still_frame = still.mean(axis=1)
    return {"mean_pct": round(float(err.mean()), 3), "p95_pct": round(float(np.percentile(err, 95)), 3),
            "max_pct": round(float(err.max()), 3), "worst_frame_pct": round(float(per_frame.max()), 3),
            "still_mean_pct": round(float(still.mean()), 3),
            "still_worst_frame_pct": round(float(still_frame.max()), 3),
            "beats_still": bool(err.mean() < still.mean())}


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """`kinetre ARGV` through the CLI's own entry point, in this process: (status, stdout, stderr)."""
    from kinetre.cli import main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


class Clip:
    """One animation of an avatar, posed by the independent player at the CLI's output frames."""

    def __init__(self, player: GltfFile, avatar: Path, anim: str, kind: str, frames: int, fps: float = 30.0):
        self.player, self.avatar, self.anim, self.kind = player, avatar, anim, kind
        self.start, end = player.time_range(anim)
        # `kinetre animate` samples a glTF clip at start + i / 30 s (its default rate for glTF sources)
        self.total = int(np.floor((end - self.start) * fps + 1e-6)) + 1
        self.fps = fps
        self.index = compared_frames(self.total, frames)
        self.times = self.start + self.index / fps
        self.reference = np.stack([player.vertices(t, anim) for t in self.times])
        self.height = height_of(player)
        self.still = errors(self.reference[:1], self.reference, self.height)
        self.label = player.doc.animations[player.animation_index(anim)].name or str(anim)

    def row(self, method: str, **fields) -> dict:
        return {"bench": "fidelity", "avatar": self.avatar.stem, "clip": self.label, "kind": self.kind,
                "method": method, "frames": len(self.index), "frames_total": self.total,
                "vertices": self.player.vertex_count, **fields}

    def played(self, out: Path) -> tuple[np.ndarray, np.ndarray]:
        """A written file posed at the compared frames (its own key times, frame i at the i-th key) and its
        rest pose."""
        result = GltfFile(out)
        keys = np.unique(np.concatenate([t.times for t in result.channels(0)]))
        posed = np.stack([result.vertices(keys[min(i, len(keys) - 1)], 0) for i in self.index])
        return posed, result.vertices(0.0, None)


def matched(rest_out: np.ndarray, rest_in: np.ndarray) -> tuple[np.ndarray, float]:
    """For each written vertex, the output vertex at its rest position, and the largest distance."""
    from scipy.spatial import cKDTree
    dist, idx = cKDTree(rest_out).query(rest_in)
    return idx, float(dist.max())


def animate_row(clip: Clip, work: Path, extra: list[str]) -> dict:
    mesh = work / f"{clip.avatar.stem}_{clip.label}.ply"
    posed0 = clip.player.vertices(clip.start, clip.anim)
    write_ply(mesh, posed0, clip.player.triangles())
    out = work / "animate.glb"
    t0 = time.perf_counter()
    status, _, stderr = run_cli(["animate", str(mesh), "--motion", f"{clip.avatar}#{clip.anim}", "-o", str(out),
                                 "-q", *extra])
    seconds = round(time.perf_counter() - t0, 2)
    notes = [line.split("kinetre: ", 1)[-1] for line in stderr.splitlines() if line.strip()]
    fields = {"skeleton": skeleton_of(clip), "seconds": seconds}
    if extra:
        fields["args"] = " ".join(extra)
    if status != 0:
        return clip.row("animate", **fields, error=" ".join(notes), within_target=False)
    posed, rest = clip.played(out)
    idx, gap = matched(rest, posed0)
    err = errors(posed[:, idx], clip.reference, clip.height)
    got = figures(err, clip.still)
    target = {**TARGETS, "mean_pct": CLIP_MEAN_TARGET.get(clip.label, TARGETS["mean_pct"])}
    row = clip.row("animate", **fields, **got, match_pct=round(100 * gap / clip.height, 6))
    if clip.kind == "humanoid":
        row.update({f"target_{k}": v for k, v in target.items()})
        row["within_target"] = all(got[k] <= v for k, v in target.items()) and got["beats_still"]
    else:
        row["within_target"] = got["beats_still"]
    if notes:
        row["notes"] = " | ".join(notes)
    return row


def avatar_row(clip: Clip, work: Path) -> dict:
    out = work / "avatar.glb"
    status, _, stderr = run_cli(["avatar", str(clip.avatar), "--motion", f"{clip.avatar}#{clip.anim}", "-o",
                                 str(out), "-q"])
    if status != 0:
        return clip.row("avatar", error=stderr.strip().split("kinetre: ", 1)[-1], within_target=False)
    posed, _ = clip.played(out)
    if posed.shape[1] != clip.player.vertex_count:
        return clip.row("avatar", error=f"the export has {posed.shape[1]} vertices, the avatar "
                                        f"{clip.player.vertex_count}", within_target=False)
    # the export is the avatar's own meshes in their own order: vertex i is vertex i
    got = figures(errors(posed, clip.reference, clip.height), clip.still)
    return clip.row("avatar", **got, target_mean_pct=AVATAR_MEAN_TARGET,
                    within_target=got["mean_pct"] <= AVATAR_MEAN_TARGET)


def skeleton_of(clip: Clip) -> str:
    """The skeleton Kinetre reads the clip as (kinect20: the person path; otherwise the shape fit)."""
    from kinetre.cli_common import load_motion
    try:
        return load_motion(f"{clip.avatar}#{clip.anim}", None).model.name
    except Exception as e:  # a refused clip: the animate row carries the message
        return f"refused ({type(e).__name__})"


def nearest_bone_row(clip: Clip) -> dict:
    """Each vertex rigidly follows the artist bone nearest to it at the clip's first frame."""
    p = clip.player
    joints = p.skin_joints()
    index = {j: k for k, j in enumerate(joints)}
    parent = []
    for j in joints:
        a = p.parent.get(j)
        while a is not None and a not in index:
            a = p.parent.get(a)
        parent.append(-1 if a is None else index[a])
    worlds = [np.stack(p.world_matrices(t, clip.anim))[joints] for t in clip.times]
    first = np.stack(p.world_matrices(clip.start, clip.anim))[joints]
    head = first[:, :3, 3]
    segments, driver = [], []
    for k, a in enumerate(parent):
        if a >= 0:
            segments.append((head[a], head[k]))
            driver.append(a)
    for k in range(len(joints)):
        if k not in parent:        # a childless joint: a point bone
            segments.append((head[k], head[k]))
            driver.append(k)
    a = np.array([s[0] for s in segments])
    b = np.array([s[1] for s in segments])
    v0 = p.vertices(clip.start, clip.anim)
    ab = b - a
    u = np.clip(np.einsum("vbc,bc->vb", v0[:, None] - a[None], ab) / np.maximum((ab * ab).sum(1), 1e-300), 0, 1)
    near = np.linalg.norm(v0[:, None] - (a[None] + u[..., None] * ab[None]), axis=2).argmin(axis=1)
    bone = np.array(driver)[near]
    local = np.einsum("vij,vj->vi", np.linalg.inv(first)[bone], np.c_[v0, np.ones(len(v0))])
    posed = np.stack([np.einsum("vij,vj->vi", w[bone], local)[:, :3] for w in worlds])
    return clip.row("nearest_bone", **figures(errors(posed, clip.reference, clip.height), clip.still))


def blender_rows(clips: list[Clip], work: Path) -> list[dict]:
    """Blender's automatic weights on one avatar's clips (one Blender run), or [] without Blender."""
    if shutil.which("blender") is None or not clips:
        return []
    avatar = clips[0].avatar
    job = {"path": str(avatar.resolve()), "fps": clips[0].fps,
           "clips": [{"animation": clip.player.animation_index(clip.anim), "name": clip.label,
                      "times": [float(t) for t in clip.times]} for clip in clips]}
    (work / "job.json").write_text(json.dumps(job))
    out = work / "blender.npz"
    done = subprocess.run(["blender", "-b", "--factory-startup", "--python", str(BLENDER_SCRIPT), "--",
                           str(work / "job.json"), str(out)], capture_output=True, text=True, timeout=1800)
    if done.returncode != 0 or not out.exists():
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
        return [clip.row("blender_auto", error=f"blender failed: {tail[0]}") for clip in clips]
    got = np.load(out)
    heat_failed = "failed to find solution" in done.stdout
    rows = []
    for k, clip in enumerate(clips):
        artist, auto = got[f"artist_{k}"], got[f"auto_{k}"]
        err = errors(auto, artist, clip.height)
        still = errors(artist[:1], artist, clip.height)
        from scipy.spatial import cKDTree
        idx = cKDTree(artist[0]).query(clip.reference[0])[1]
        check = errors(artist[:, idx], clip.reference, clip.height).mean()
        rows.append(clip.row("blender_auto", **figures(err, still), reference_check_pct=round(float(check), 4),
                             heat_failed_on_some_bones=heat_failed))
    return rows


def write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """A binary PLY of positions and triangles only: the unrigged mesh a user would bring."""
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\nproperty float x\n"
              f"property float y\nproperty float z\nelement face {len(faces)}\n"
              "property list uchar int vertex_indices\nend_header\n").encode()
    tri = np.zeros(len(faces), dtype=[("n", "u1"), ("v", "<i4", 3)])
    tri["n"], tri["v"] = 3, faces
    path.write_bytes(header + vertices.astype("<f4").tobytes() + tri.tobytes())


def avatars(names) -> list[tuple[Path, str]]:
    return [(DATA / "avatars" / f"{name}.glb", kind) for name, kind in names.items()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--avatar", type=Path, help="one rigged .glb (default: every public avatar)")
    ap.add_argument("--anim", action="append", help="animation name or index (repeatable; default: every one)")
    ap.add_argument("--kind", default=None, choices=("humanoid", "quadruped", "other"),
                    help="what --avatar is (default: humanoid)")
    ap.add_argument("--frames", type=int, default=FRAMES, help=f"compared frames per clip (default {FRAMES})")
    ap.add_argument("--methods", default="animate,avatar,nearest_bone,blender_auto",
                    help="comma-separated subset of animate, avatar, nearest_bone, blender_auto")
    ap.add_argument("--animate-args", default="", help="extra `kinetre animate` arguments, e.g. '--nodes 256'")
    args = ap.parse_args()
    methods = set(args.methods.split(","))
    todo = [(args.avatar, args.kind or "humanoid")] if args.avatar else avatars(AVATARS)
    with tempfile.TemporaryDirectory(prefix="kinetre-fidelity-") as tmp:
        work = Path(tmp)
        for path, kind in todo:
            player = GltfFile(path)
            anims = args.anim or [a.name if a.name else str(i) for i, a in enumerate(player.doc.animations)]
            clips = [Clip(player, path, anim, kind, args.frames) for anim in anims]
            for clip in clips:
                if "animate" in methods:
                    print(json.dumps(animate_row(clip, work, args.animate_args.split())), flush=True)
                if "avatar" in methods and kind == "humanoid":
                    print(json.dumps(avatar_row(clip, work)), flush=True)
                if "nearest_bone" in methods:
                    print(json.dumps(nearest_bone_row(clip)), flush=True)
            if "blender_auto" in methods:
                for row in blender_rows(clips, work):
                    print(json.dumps(row), flush=True)
    if "blender_auto" in methods and shutil.which("blender") is None:
        print("bench_fidelity: blender is not on PATH: no blender_auto rows", file=sys.stderr)


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
