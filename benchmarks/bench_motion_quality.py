"""Motion quality (kinetre.motion.quality) before and after cleaning (kinetre.motion.cleanup), over the public
videos and mocap in ../shared/data.

Prints one JSON object per line, {"bench": "motion_quality", "case": ...}:

* "camera", per video: the take as tracked (no filter), as `kinetre capture` used to write it (the tracker's
  causal One-Euro), cleaned offline (zero-lag smoothing, feet held), and cleaned live (causal, no delay).
  Every version is measured over the offline cleaning's stance frames. Targets: planted-foot slide p95 and
  vertical bob p95 <= 1 cm offline; jitter at most half the tracked take's; live lag <= one frame (33 ms).
* "mocap", per BVH at 30 fps with --contact (feet held, no smoothing): the frames where both feet are off the
  floor must match the original's within 1 frame (the worst jump boundary), and each jump's peak hip height
  within 2 cm.
* "mesh": a figure dressed on the first video's first frame, possessed by its take (`kinetre animate
  --report`, cleaned by default, and `--raw` for comparison): its lowest contact regions' slide p95 <= 1.5 cm.

Tracking a video with MediaPipe is CPU heavy: `--frames N` limits each video to its first N frames.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from kinetre.motion.capture import CaptureSettings, capture_video
from kinetre.motion.cleanup import CleanupSettings, LiveCleaner, clean_take, clean_track
from kinetre.motion.contact import contact_joints, detect_stance, runs
from kinetre.motion.filters import one_euro
from kinetre.motion.quality import measure
from kinetre.motion.source import load_take, resample
from kinetre.motion.stream import write_stream
from kinetre.motion.take import camera_viewpoint

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
MOCAP = ("cmu_01_01_hops", "cmu_12_01_walk", "mocapbank_test")


def figures(q) -> dict:
    d = q.to_dict()
    return {k: d[k] for k in ("jitter", "jitter_noise", "skate_speed", "slide_p95", "bob_p95", "penetration",
                              "floating", "stance", "airborne", "lag_ms")}


def camera(path: Path, frames: int | None) -> tuple[dict, object]:
    settings = CaptureSettings(smooth=False, hands=False, face=False)
    take = capture_video(path, settings, max_frames=frames)
    model, fps, raw = take.model, take.fps, take.positions
    joints = contact_joints(model, raw)
    names = tuple(model.joints[j] for j in joints)
    view = camera_viewpoint(take)
    offline = clean_track(model, raw, fps, viewpoint=view)
    stance = offline.stance
    causal = one_euro(raw, fps, 1.0, 20.0)  # what the tracker's own filter gives (CaptureSettings defaults)
    live = LiveCleaner(model, viewpoint=view)
    live_pos = np.stack([live(raw[i], i / fps) for i in range(len(raw))])
    q = {name: measure(p, fps, joints, names, stance, raw) for name, p in
         (("tracked", raw), ("tracker_filter", causal), ("offline", offline.positions), ("live", live_pos))}
    off, trk = q["offline"], q["tracked"]
    record = {"bench": "motion_quality", "case": "camera", "clip": path.name, "frames": len(take), "fps": fps,
              **{f"{name}": figures(value) for name, value in q.items()},
              "slide_p95_cm": round(off.slide_p95, 4), "bob_p95_cm": round(off.bob_p95, 4),
              "jitter_ratio": round(off.jitter / trk.jitter, 4),
              "live_jitter_ratio": round(q["live"].jitter / trk.jitter, 4),
              "live_lag_ms": round(q["live"].lag_ms, 2), "live_lag_abs_ms": round(abs(q["live"].lag_ms), 2),
              "offline_lag_ms": round(off.lag_ms, 2),
              "targets": {"slide_p95_cm": 1.0, "bob_p95_cm": 1.0, "jitter_ratio": 0.5, "live_lag_ms": 1000 / 30},
              "load_average": round(os.getloadavg()[0], 1)}
    record["met"] = bool(off.slide_p95 <= 1.0 and off.bob_p95 <= 1.0 and off.jitter <= trk.jitter / 2
                         and abs(q["live"].lag_ms) <= 1000 / 30)
    return record, take


def jumps(positions: np.ndarray, fps: float, joints) -> tuple[list[tuple[int, int]], np.ndarray]:
    stance = detect_stance(positions, fps, joints)
    return [r for r in runs(stance.airborne()) if r[1] - r[0] >= 2], stance.airborne()


def mocap(name: str) -> dict:
    take = resample(load_take(DATA / "bvh" / f"{name}.bvh"), 30.0)
    model, fps, pos = take.model, take.fps, take.positions
    joints = contact_joints(model, pos)
    out = clean_track(model, pos, fps, CleanupSettings(smooth=False), take.bone_frames)
    before, air0 = jumps(pos, fps, joints)
    after, air1 = jumps(out.positions, fps, joints)
    stance = out.stance
    names = tuple(model.joints[j] for j in joints)
    q0, q1 = measure(pos, fps, joints, names, stance), measure(out.positions, fps, joints, names, stance)
    # each original jump against the corrected jump overlapping it most
    worst_frames, worst_peak = 0, 0.0
    for a, b in before:
        match = [(min(b, d) - max(a, c), (c, d)) for c, d in after if min(b, d) > max(a, c)]
        if not match:
            worst_frames = max(worst_frames, b - a)
            continue
        c, d = max(match)[1]
        worst_frames = max(worst_frames, abs(a - c), abs(b - d))
        hip = 0
        worst_peak = max(worst_peak, abs(out.positions[a:b, hip, 1].max() - pos[a:b, hip, 1].max()))
    return {"bench": "motion_quality", "case": "mocap", "clip": name, "frames": len(take), "fps": fps,
            "jumps": len(before), "jumps_after": len(after),
            "airborne_frames": int(air0.sum()), "airborne_frames_after": int(air1.sum()),
            "jump_boundary_frames": worst_frames, "jump_peak_cm": round(100 * worst_peak, 3),
            "before": figures(q0), "after": figures(q1),
            "targets": {"jump_boundary_frames": 1, "jump_peak_cm": 2.0},
            "met": bool(worst_frames <= 1 and worst_peak <= 0.02 and len(before) == len(after))}


def possess(take, mesh_path: Path, *extra: str) -> dict:
    """`kinetre animate MESH --motion TAKE --report` in this process; the report."""
    from kinetre.cli.main import main as cli
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "take.kinetre.jsonl"
        write_stream(src, take)
        report = Path(tmp) / "report.json"
        code = cli(["animate", str(mesh_path), "--motion", str(src), "-o", str(Path(tmp) / "out.glb"),
                    "--report", str(report), "-q", *extra])
        if code:
            raise SystemExit(f"kinetre animate failed ({code})")
        return json.loads(report.read_text())


def dressed(take, path: Path) -> Path:
    """A figure dressed on the take's first frame (capsules round its bones, as tests/synthetic.py builds
    them), written as an OBJ: a mesh the skeleton fits, so what slides is the motion."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from synthetic import capsule_body
    import trimesh
    body = capsule_body(take.frame(0), radius=0.05)
    trimesh.Trimesh(body.vertices, body.faces, process=False).export(path)
    return path


def mesh(take) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        # each run possesses a figure dressed on the first frame it binds to (cleaning moves the body)
        rep = possess(take, dressed(clean_take(take), Path(tmp) / "figure.obj"))
        raw = possess(take, dressed(take, Path(tmp) / "raw_figure.obj"), "--raw")
    mc = rep["mesh_contacts"]
    return {"bench": "motion_quality", "case": "mesh", "mesh": "capsule figure on frame 0",
            "motion": Path(take.source).name, "frames": len(take), "regions": len(mc["contacts"]),
            "mesh_slide_p95_cm": mc["slide_p95"], "mesh_bob_p95_cm": mc["bob_p95"],
            "mesh_skate_speed": mc["skate_speed"], "take_slide_p95_cm": rep["take"]["slide_p95"],
            "raw_mesh_slide_p95_cm": raw["mesh_contacts"]["slide_p95"],
            "raw_mesh_bob_p95_cm": raw["mesh_contacts"]["bob_p95"],
            "applied": sorted(k for k in rep["applied"] or {}), "targets": {"mesh_slide_p95_cm": 1.5},
            "met": mc["slide_p95"] is not None and mc["slide_p95"] <= 1.5}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=None, help="track at most this many frames of each video")
    ap.add_argument("--no-mesh", action="store_true", help="skip the possessed-mesh case")
    args = ap.parse_args()
    os.environ.setdefault("GLOG_minloglevel", "2")
    taken = None
    for path in sorted((DATA / "video").glob("*.mp4")):
        record, take = camera(path, args.frames)
        print(json.dumps(record), flush=True)
        taken = taken or take
    for name in MOCAP:
        print(json.dumps(mocap(name)), flush=True)
    if taken is not None and not args.no_mesh:
        print(json.dumps(mesh(taken)), flush=True)


if __name__ == "__main__":
    sys.exit(main())
