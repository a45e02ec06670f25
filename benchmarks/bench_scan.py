"""Scanning speed: frames per second of tracking + TSDF fusion at 640x480 on the CPU.

1. "scan_fuse": the real Redwood living-room frames (5 frames, 640x480), tracked (features + dense odometry,
   scored against the model) and integrated at three voxel sizes;
2. "scan_orbit": `fuse_sequence` on a synthetic 40-frame 360-degree orbit of the desk lamp (tests/scan), 640x480
   at 6 mm, frames read from disk, for each tracking design in DESIGNS at one and two threads. `cpu_fps` is the
   per-frame pipeline (read, track, fuse) in frames per CPU second; loop closure and the second fusion at the
   optimised poses run once per scan and are reported apart (`closing_cpu_s`), with the trajectory error
   against the ground truth before and after them (`rmse_mm_tracked`, `rmse_mm`);
3. "scan_stages": CPU milliseconds per frame of each stage of the default design (cProfile on the process clock).

One JSON object per line. Open3D and numba are warmed up before timing. On a shared machine `cpu_fps` (frames
per CPU second) is the steadier figure; `load` is the 1-minute load average when the record was taken.
"""
from __future__ import annotations

import cProfile
import json
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from threadpoolctl import threadpool_limits

from kinetre.scan.frames import open_sequence, read_frame
from kinetre.scan.fuse import TSDFVolume
from kinetre.scan.pipeline import fuse_sequence
from kinetre.scan.recent import RecentFrames
from kinetre.scan.track import TrackingParams, track_frame

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
VOXELS = (0.02, 0.01, 0.006)
REPEATS = 2  # passes over the 5 frames (a new model each pass)
DEFAULT = "odometry at 320x240, up to (10, 10) iterations until settled, scored at 160x120"
DESIGNS = {
    # the tracker before the halved-resolution odometry: iterating at 640x480 (3 at 320x240, 6 at 640x480),
    # scored at 320x240
    "odometry at 640x480": TrackingParams(odometry_iterations=(0, 3, 6), odometry_tolerance=1e-6,
                                          odometry_width=640, score_width=320),
    "odometry at 320x240, fixed (6, 4) iterations, scored at 160x120":
        TrackingParams(odometry_iterations=(6, 4), odometry_tolerance=1e-6),
    DEFAULT: TrackingParams(),
}
STAGES = {  # stage: functions (file name suffix, function name) whose cumulative CPU time it is
    "read": [("frames.py", "read_frame")],
    "features": [("features.py", "feature_motion")],
    "odometry": [("track.py", "dense_motion")],
    "score": [("track.py", "_score")],
    "model_icp": [("track.py", "_model_icp")],
    "integrate": [("fuse.py", "integrate")],
}


def _threads(count: int):
    cv2.setNumThreads(count)  # OpenCV's own pool (ORB, matching) is not OpenMP
    return threadpool_limits(limits=count, user_api="openmp")


def run(voxel: float, threads: int, frames) -> dict:
    camera = frames[0][2]
    seconds = cpu = 0.0
    count = 0
    for _ in range(REPEATS):
        volume = TSDFVolume(voxel)
        recent = RecentFrames()
        previous = None
        start, cpu_start = time.perf_counter(), time.process_time()
        for color, depth, _ in frames:
            if previous is None:
                pose = np.eye(4)
            else:
                result = track_frame(volume, color, depth, camera, previous, recent=recent)
                if not result.accepted:
                    raise SystemExit(f"bench_scan: tracking lost on real frames at voxel {voxel}: {result.reason}")
                pose = result.pose
            volume.integrate(color, depth, camera, pose)
            previous = (color, depth, pose)
            count += 1
        seconds += time.perf_counter() - start
        cpu += time.process_time() - cpu_start
    return {"bench": "scan_fuse", "voxel_m": voxel, "threads": threads, "width": camera.width,
            "height": camera.height, "frames": count, "fps": round(count / seconds, 3), "cpu_fps": round(count / cpu, 3),
            "seconds": round(seconds, 3), "cpu_s": round(cpu, 3), "blocks": int(volume.grid.hashmap().size()),
            "load": round(os.getloadavg()[0], 1)}


def _rmse_mm(poses: list, truth: np.ndarray) -> float:
    truth = np.linalg.inv(truth[0]) @ truth  # the scan's world is its first camera
    error = np.linalg.norm(np.array(poses)[:, :3, 3] - truth[:, :3, 3], axis=1)
    return round(float(np.sqrt(np.mean(error ** 2))) * 1000, 2)


def orbit(folder: Path, truth: np.ndarray, design: str, threads: int) -> dict:
    sequence = open_sequence(folder)
    volume = TSDFVolume(0.006)
    start, cpu_start = time.perf_counter(), time.process_time()
    fused = fuse_sequence(sequence, volume, DESIGNS[design], progress=False)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    count = len(sequence)
    frame_cpu = cpu - fused.closing_cpu
    return {"bench": "scan_orbit", "design": design, "voxel_m": 0.006, "threads": threads,
            "width": sequence.intrinsics.width, "height": sequence.intrinsics.height, "frames": count,
            "used": int(sum(fused.accepted)), "cpu_fps": round(count / frame_cpu, 3),
            "cpu_ms_per_frame": round(frame_cpu / count * 1000, 1), "loops": fused.loops,
            "closing_cpu_s": round(fused.closing_cpu, 2), "rmse_mm_tracked": _rmse_mm(fused.tracked, truth),
            "rmse_mm": _rmse_mm(fused.poses, truth), "fps_with_closing": round(count / seconds, 3),
            "cpu_fps_with_closing": round(count / cpu, 3), "blocks": int(volume.grid.hashmap().size()),
            "load": round(os.getloadavg()[0], 1)}


def stages(folder: Path) -> dict:
    sequence = open_sequence(folder)
    profile = cProfile.Profile(time.process_time)
    profile.enable()
    fuse_sequence(sequence, TSDFVolume(0.006), TrackingParams(), progress=False, close_loops=False)
    profile.disable()
    table = pstats.Stats(profile).stats  # (file, line, name) -> (calls, primitive, tottime, cumtime, callers)
    total = sum(row[2] for row in table.values())
    record = {"bench": "scan_stages", "design": DEFAULT, "threads": 1,
              "frames": len(sequence), "total_ms": round(total / len(sequence) * 1000, 1)}
    for stage, functions in STAGES.items():
        cumulative = sum(row[3] for (path, _, name), row in table.items()
                         if any(path.endswith(f) and name == n for f, n in functions))
        record[f"{stage}_ms"] = round(cumulative / len(sequence) * 1000, 1)
    record["load"] = round(os.getloadavg()[0], 1)
    return record


def main() -> None:
    sequence = open_sequence(DATA / "rgbd" / "redwood_livingroom")
    frames = [(*read_frame(sequence, i), sequence.intrinsics) for i in range(len(sequence))]
    run(VOXELS[0], 1, frames[:2])  # warm-up: first calls allocate Open3D's buffers and load numba's cache
    for threads in (1, 2):
        with _threads(threads):
            for voxel in VOXELS:
                print(json.dumps(run(voxel, threads, frames)), flush=True)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "scan"))
    import scan_synthetic
    with tempfile.TemporaryDirectory(prefix="bench-scan-") as tmp:
        lamp = scan_synthetic.render_orbit("lamp", 40, 640, 480)
        lamp.write(Path(tmp))
        with _threads(1):
            print(json.dumps(stages(Path(tmp))), flush=True)
        for design in DESIGNS:
            for threads in (1, 2):
                with _threads(threads):
                    print(json.dumps(orbit(Path(tmp), lamp.poses, design, threads)), flush=True)


if __name__ == "__main__":
    main()
