"""`kinetre animate` end to end on a ~386k-vertex mesh (the Loop-subdivided elephant), timed as a user runs it.

Records (one JSON object per line, "bench": "animate"):

* `"numba_cache": "cold"`: a first-ever run in a fresh process with a new, empty numba cache, which compiles
  every kernel (seconds, most of them in the graph stage); per-stage seconds and CPU seconds. Then
  `kinetre kernels` runs on that cache, as `make setup` does (the kernels compiled ahead of time), and every
  record below reads it.
* `"numba_cache": "warm", "clip": "walk 3 s"`: the whole command in a fresh process, as a user types it —
  `python -m kinetre.cli animate elephant.ply --motion walk.bvh -o out.glb --max-frames 90 --fps 30 -q`:
  interpreter start, imports, load, graph, attach, solve, GLB write. `wall_s` / `cpu_s` are the best of
  five runs (CPU = user + system of the child, from getrusage(RUSAGE_CHILDREN): what the command costs on
  a shared machine), `*_median` the middle one. `realtime_factor` = clip seconds / wall seconds (> 1: faster
  than the clip plays), `cpu_realtime_factor` the same with CPU seconds. The per-stage figures (`load_s`,
  `load_cpu`, ...) come from one more warm run measured inside the process (`cmd_animate`'s stats; CPU of
  every thread: the skinning weights run in a thread beside attach and solve, `weights_cpu`, and
  `main_thread_cpu_s` is the command's own thread, what the wall time approaches with a free core).
  The children run with Python's bytecode cache on, as an installed package does, whatever
  PYTHONDONTWRITEBYTECODE says here.
* `"clip": "hops 23 s"`: the same whole-command timing on a longer clip (the whole 23 s CMU hops at 30 fps).
* `"bench": "animate_startup"`: `kinetre --help` and an argument error, whole process.
* `"bench": "animate_after_setup"`: the first `kinetre animate` a user runs once `make setup` is done: a
  mesh of about 13k vertices it has never seen (spot, subdivided once) and the 3 s walk, in a fresh process
  with the kernels `make setup` cached and an empty mesh cache, whole command.

Every whole-command record says which preprocessing it measured in `"mesh_cache"`: `"off"` runs with
`--no-cache` (the mesh loaded and cleaned, its graph and weights built, in every run: a mesh the command has
not seen), `"kept"` with the command's default, after one uncounted run has kept the mesh's cleaned arrays,
graph and weights in the cache (`kinetre.preprocessed`; a mesh animated before). The cache folder is a new
one under the bench's temporary folder; the kernels stay where they are (NUMBA_CACHE_DIR is set to the folder
they are read from). The in-process stage figures are those of a run with `--no-cache`.

`--quick` (make bench-quick): only the after-setup record and the hops records, three runs each, with the kernels `make setup` cached (the
environment's NUMBA_CACHE_DIR, else the user's cache) instead of a new, empty cache.

An earlier version of this bench ran first in `make bench` on a fresh clone and so reported the cold figure
as the graph stage's cost; the version before this one timed only the stages inside a running interpreter.
"""
from __future__ import annotations

import gzip
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
WALK = DATA / "bvh" / "cmu_12_01_walk.bvh"
HOPS = DATA / "bvh" / "cmu_01_01_hops.bvh"
FRAMES = 90  # 3 s of the walk at 30 fps
RUNS = 5


def _animate_argv(mesh: Path, motion: Path, out: Path, frames: int | None, kept: bool = False) -> list[str]:
    argv = ["animate", str(mesh), "--motion", str(motion), "-o", str(out), "--fps", "30", "-q"]
    return argv + (["--max-frames", str(frames)] if frames else []) + ([] if kept else ["--no-cache"])


def _kept_and_off(argv_of, env: dict, clip_s: float, runs: int) -> list[dict]:
    """The whole-command figures with the mesh's preprocessing kept (after one uncounted run keeps it) and
    with `--no-cache`."""
    out = []
    for kept in (True, False):
        argv = argv_of(kept)
        if kept:
            _child(argv, env)
        out.append({"mesh_cache": "kept" if kept else "off", **_whole(argv, env, clip_s, runs)})
    return out


def _child(argv: list[str], env: dict) -> tuple[float, float, int]:
    """(wall s, CPU s, exit status) of `python -m kinetre.cli ARGV` in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "kinetre.cli", *argv], env=env, capture_output=True, timeout=600)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, done.returncode


def _whole(argv: list[str], env: dict, clip_s: float, runs_wanted: int = RUNS) -> dict:
    runs = []
    for _ in range(runs_wanted):
        wall, cpu, status = _child(argv, env)
        if status != 0:
            raise SystemExit(f"kinetre {' '.join(argv)} exited with {status}")
        runs.append((wall, cpu))
    walls, cpus = sorted(w for w, _ in runs), sorted(c for _, c in runs)
    mid = len(runs) // 2
    return {"clip_s": round(clip_s, 2), "runs": len(runs), "wall_s": round(walls[0], 2), "cpu_s": round(cpus[0], 2),
            "wall_s_median": round(walls[mid], 2), "cpu_s_median": round(cpus[mid], 2),
            "realtime_factor": round(clip_s / walls[0], 2), "cpu_realtime_factor": round(clip_s / cpus[0], 2),
            "realtime_factor_median": round(clip_s / walls[mid], 2),
            "cpu_realtime_factor_median": round(clip_s / cpus[mid], 2)}


def stages(mesh: Path, out: Path) -> dict:
    """One run inside this process: `cmd_animate`'s per-stage seconds and CPU seconds."""
    from kinetre.cli import build_parser
    from kinetre.cli.animate import cmd_animate

    args = build_parser().parse_args(_animate_argv(mesh, WALK, out, FRAMES))
    stats: dict = {}
    cpu, main_cpu = time.process_time(), time.thread_time()
    cmd_animate(args, stats)
    cpu, main_cpu = time.process_time() - cpu, time.thread_time() - main_cpu
    record = {"vertices": stats["vertices"], "nodes": stats["nodes"], "frames": stats["frames"],
              "glb_mb": round(out.stat().st_size / 2**20, 1), "stages_cpu_s": round(cpu, 2),
              "main_thread_cpu_s": round(main_cpu, 2),
              "solve_fps": round(stats["frames"] / stats["solve_s"], 1)}
    record.update({k: round(v, 2) for k, v in stats.items() if k.endswith(("_s", "_cpu"))})
    return record


def ply_vertex_count(path: Path) -> int | None:
    """The vertex count a PLY header declares (no need to load the mesh for the record)."""
    with open(path, "rb") as f:
        for line in f:
            if line.startswith(b"element vertex"):
                return int(line.split()[2])
            if line.strip() == b"end_header":
                return None
    return None


def hops_records(mesh: Path, tmp: Path, env: dict, runs: int, vertices: int | None) -> list[dict]:
    from kinetre.motion.source import load_take, resample
    hops_frames = len(resample(load_take(str(HOPS)), 30.0))  # the whole 22.9 s clip at 30 fps
    both = _kept_and_off(lambda kept: _animate_argv(mesh, HOPS, tmp / "hops.glb", None, kept), env,
                         hops_frames / 30.0, runs)
    return [{"bench": "animate", "numba_cache": "warm", "clip": "hops 23 s", "whole_process": True,
             "frames": hops_frames, "vertices": vertices, **hops} for hops in both]


def after_setup_record(tmp: Path) -> dict:
    """The first animate after `make setup` of a ~13k-vertex mesh not seen before (see the module's notes)."""
    import trimesh
    from kinetre.jit import kernel_cache_dir
    spot = trimesh.load(Path(__file__).resolve().parents[1] / "src" / "kinetre" / "data" / "spot.obj", force="mesh",
                        process=False)
    mesh = tmp / "spot_13k.ply"
    trimesh.Trimesh(*trimesh.remesh.subdivide(spot.vertices, spot.faces), process=False).export(mesh)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(kernel_cache_dir()), XDG_CACHE_HOME=str(tmp / "first-cache"))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    wall, cpu, status = _child(_animate_argv(mesh, WALK, tmp / "first.glb", FRAMES, kept=True), env)
    if status != 0:
        raise SystemExit(f"kinetre animate {mesh} exited with {status}")
    return {"bench": "animate_after_setup", "mesh": "spot subdivided", "vertices": ply_vertex_count(mesh),
            "clip": "walk 3 s", "wall_s": round(wall, 2), "cpu_s": round(cpu, 2)}


def _environment(quick: bool, cache: str, tmp: Path) -> dict:
    """The children's environment: the kernels read from where they are (quick: those `make setup` cached)
    or compiled into the new folder `cache`; the mesh cache in a new folder under `tmp`."""
    if quick:
        from kinetre.jit import kernel_cache_dir
        cache = str(kernel_cache_dir())
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, XDG_CACHE_HOME=str(tmp / "user-cache"))
    # as installed: Python's bytecode cache on (an environment that turns it off recompiles every
    # kinetre module in every run, 0.12 s more)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def main(quick: bool = False) -> None:
    with tempfile.TemporaryDirectory() as tmp, tempfile.TemporaryDirectory() as cache:
        tmp = Path(tmp)
        mesh = tmp / "elephant_loop3_large.ply"
        with gzip.open(DATA / "meshes" / "elephant_loop3_large.ply.gz", "rb") as src, open(mesh, "wb") as dst:
            shutil.copyfileobj(src, dst)
        print(json.dumps(after_setup_record(tmp)), flush=True)
        env = _environment(quick, cache, tmp)
        if quick:
            for record in hops_records(mesh, tmp, env, 3, ply_vertex_count(mesh)):
                print(json.dumps(record), flush=True)
            return
        once = [sys.executable, __file__, "--stages", str(mesh), str(tmp / "stages.glb")]

        def run_stages() -> dict:
            out = subprocess.run(once, env=env, check=True, capture_output=True, text=True, timeout=1200).stdout
            return json.loads(out.strip().splitlines()[-1])

        cold = run_stages()
        print(json.dumps({"bench": "animate", "numba_cache": "cold", **cold}), flush=True)
        subprocess.run([sys.executable, "-m", "kinetre.cli", "kernels", "-q"], env=env, check=True, timeout=1200)
        warm = run_stages()
        for walk in _kept_and_off(lambda kept: _animate_argv(mesh, WALK, tmp / "walk.glb", FRAMES, kept), env,
                                  FRAMES / 30.0, RUNS):
            print(json.dumps({"bench": "animate", "numba_cache": "warm", "clip": "walk 3 s", "whole_process": True,
                              **walk, **warm}), flush=True)
        for record in hops_records(mesh, tmp, env, RUNS, warm["vertices"]):
            print(json.dumps(record), flush=True)
        help_wall, help_cpu, _ = _child(["--help"], env)
        err_wall, err_cpu, status = _child(["animate", str(mesh)], env)  # no --motion: an argument error
        print(json.dumps({"bench": "animate_startup", "help_wall_s": round(help_wall, 2),
                          "help_cpu_s": round(help_cpu, 2), "argument_error_wall_s": round(err_wall, 2),
                          "argument_error_cpu_s": round(err_cpu, 2), "argument_error_status": status}), flush=True)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--stages"]:
        print(json.dumps(stages(Path(sys.argv[2]), Path(sys.argv[3]))), flush=True)
    else:
        main(quick=sys.argv[1:2] == ["--quick"])
