"""Scanning speed: frames per second of tracking + TSDF fusion at 640x480 on the CPU.

1. "scan_fuse": the real Redwood living-room frames (5 frames, 640x480), tracked (features + dense odometry,
   scored against the model) and integrated at three voxel sizes;
2. "scan_orbit": `fuse_sequence` on a synthetic 40-frame 360-degree orbit of the desk lamp (tests/scan), 640x480
   at 6 mm: tracking, fusion, loop closure and the second fusion at the optimised poses, frames read from disk.

One JSON object per line: {"bench", "voxel_m", "threads", "frames", "fps", "cpu_fps", "seconds", "cpu_s",
"blocks"}. Open3D is warmed up before timing; KinectFusion ran at 30 fps on a 2011 GPU. On a shared machine
`cpu_fps` (frames per CPU second) is the steadier figure.
"""
from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from kinetre.scan.frames import open_sequence, read_frame
from kinetre.scan.fuse import TSDFVolume
from kinetre.scan.pipeline import fuse_sequence
from kinetre.scan.track import TrackingParams, track_frame

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
VOXELS = (0.02, 0.01, 0.006)
REPEATS = 2  # passes over the 5 frames (a new model each pass)


def run(voxel: float, threads: int, frames) -> dict:
    camera = frames[0][2]
    seconds = cpu = 0.0
    count = 0
    for _ in range(REPEATS):
        volume = TSDFVolume(voxel)
        previous = None
        start, cpu_start = time.perf_counter(), time.process_time()
        for color, depth, _ in frames:
            if previous is None:
                pose = np.eye(4)
            else:
                result = track_frame(volume, color, depth, camera, previous)
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
            "seconds": round(seconds, 3), "cpu_s": round(cpu, 3), "blocks": int(volume.grid.hashmap().size())}


def orbit(folder: Path, threads: int) -> dict:
    sequence = open_sequence(folder)
    volume = TSDFVolume(0.006)
    start, cpu_start = time.perf_counter(), time.process_time()
    fused = fuse_sequence(sequence, volume, TrackingParams(), progress=False)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    count = len(sequence)
    return {"bench": "scan_orbit", "voxel_m": 0.006, "threads": threads, "width": sequence.intrinsics.width,
            "height": sequence.intrinsics.height, "frames": count, "used": int(sum(fused.accepted)),
            "loops": fused.loops, "fps": round(count / seconds, 3), "cpu_fps": round(count / cpu, 3),
            "seconds": round(seconds, 3), "cpu_s": round(cpu, 3), "blocks": int(volume.grid.hashmap().size())}


def main() -> None:
    sequence = open_sequence(DATA / "rgbd" / "redwood_livingroom")
    frames = [(*read_frame(sequence, i), sequence.intrinsics) for i in range(len(sequence))]
    run(VOXELS[0], 1, frames[:2])  # warm-up: first calls allocate Open3D's buffers
    for threads in (1, 2):
        with threadpool_limits(limits=threads, user_api="openmp"):
            for voxel in VOXELS:
                print(json.dumps(run(voxel, threads, frames)), flush=True)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "scan"))
    import scan_synthetic
    with tempfile.TemporaryDirectory(prefix="bench-scan-") as tmp:
        scan_synthetic.render_orbit("lamp", 40, 640, 480).write(Path(tmp))
        for threads in (1, 2):
            with threadpool_limits(limits=threads, user_api="openmp"):
                print(json.dumps(orbit(Path(tmp), threads)), flush=True)


if __name__ == "__main__":
    main()
