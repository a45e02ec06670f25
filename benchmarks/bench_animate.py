"""`kinetre animate` end to end on a ~386k-vertex mesh (the Loop-subdivided elephant) with the CMU walk.

Prints two JSON objects {"bench": "animate", "numba_cache": "cold"|"warm", "vertices", "frames", "fps", stage
seconds...}; fps is output frames per second of wall time for the whole command (load, graph, attach, solve,
GLB), the target being faster than real time at 30 fps (realtime_factor > 1; cpu_fps and cpu_realtime_factor
count CPU time instead, the meaningful figure on a shared machine).

Each figure comes from a fresh process sharing a new, empty numba cache: the first ("cold") is a first-ever
run, which compiles every kernel (seconds, most of them in the graph stage); the second ("warm") loads them
from the cache, as every later run does. An earlier version of this bench ran first in `make bench` on a
fresh clone and so reported the cold figure as the graph stage's cost.
"""
from __future__ import annotations

import gzip
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from kinetre.cli import build_parser, cmd_animate

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
FRAMES = 90  # 3 s of the walk at 30 fps


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        mesh = Path(tmp) / "elephant_loop3_large.ply"
        with gzip.open(DATA / "meshes" / "elephant_loop3_large.ply.gz", "rb") as src, open(mesh, "wb") as dst:
            shutil.copyfileobj(src, dst)
        args = build_parser().parse_args(["animate", str(mesh), "--motion", str(DATA / "bvh" / "cmu_12_01_walk.bvh"),
                                          "-o", str(Path(tmp) / "elephant.glb"), "--max-frames", str(FRAMES),
                                          "--fps", "30", "-q"])
        stats: dict = {}
        cpu = time.process_time()
        cmd_animate(args, stats)
        cpu = time.process_time() - cpu
        glb_mb = (Path(tmp) / "elephant.glb").stat().st_size / 2**20
    record = {"bench": "animate", "vertices": stats["vertices"], "nodes": stats["nodes"], "frames": stats["frames"],
              "fps": round(stats["frames"] / stats["total_s"], 2),
              "solve_fps": round(stats["frames"] / stats["solve_s"], 1), "glb_mb": round(glb_mb, 1),
              "cpu_s": round(cpu, 2),  # CPU seconds of this process: wall time minus waiting for a shared core
              "clip_s": round(stats["frames"] / 30.0, 2),
              # > 1: the whole command (load, graph, attach, solve, write) is faster than the clip plays
              "realtime_factor": round(stats["frames"] / 30.0 / stats["total_s"], 2),
              "cpu_fps": round(stats["frames"] / cpu, 1), "cpu_realtime_factor": round(stats["frames"] / 30.0 / cpu, 2)}
    record.update({k: round(v, 2) for k, v in stats.items() if k.endswith(("_s", "_cpu"))})
    print(json.dumps(record), flush=True)


if __name__ == "__main__":
    if sys.argv[1:] == ["--once"]:
        main()
    else:
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            for label in ("cold", "warm"):
                out = subprocess.run([sys.executable, __file__, "--once"], env=env, check=True, capture_output=True,
                                     text=True, timeout=1200).stdout
                record = json.loads(out.strip().splitlines()[-1])
                print(json.dumps({"bench": "animate", "numba_cache": label, **record}), flush=True)
