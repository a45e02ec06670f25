"""Issue 9's local/global solver against the default, measured alike: per frame each design solves from its
own warm state three times (state restored in between), the least CPU time of the solving thread counts;
the designs take turns frame by frame, so a shared machine's load falls on all of them alike.

The frames are bench_core's solve records' (the walk at 30 fps, a second skeleton 3 cm aside, 256 and 512
nodes), plus one arm possessing the body (128 nodes, the hard case for agreement). Prints one JSON object
per line. Run on one core: OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1.
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

import kinetre
from kinetre.deform.solver import SolverSettings
from kinetre.motion.bvh import load_bvh

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_core import DATA, DESIGNS as CORE_DESIGNS, capsule_body  # noqa: E402

DESIGNS = {"pcg_default": CORE_DESIGNS["pcg_half_cycle"],
           **{name: CORE_DESIGNS[name] for name in ("local_global", "local_global_two_then_pcg", "local_global_alone",
                                                    "local_global_alone_tight")}}
STATE = ("_lam", "_lam_exact", "_last_energy", "_jump_left")  # what a solve carries to the next frame


def timed_solve(rig, frame, repeats):
    """Least thread CPU seconds of `repeats` solves of `frame`, each from the state before the first."""
    x, before = rig._x.copy(), rig._x_before
    state = {k: getattr(rig.solver, k) for k in STATE if hasattr(rig.solver, k)}
    best = np.inf
    for r in range(repeats):
        if r:
            rig._x, rig._x_before = x.copy(), before
            for k, v in state.items():
                setattr(rig.solver, k, v)
        c = time.thread_time()
        rig.solve(frame)
        best = min(best, time.thread_time() - c)
    return best


def compare(nodes, skeletons, subset=None, repeats=3):
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, len(take), 4)]
    second = [f.transformed(translation=(0.03, 0.0, 0.02)) for f in frames[10:] + frames[:10]]
    graph = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=nodes)
    binds = [frames[0], second[0]][:skeletons]
    names = ["exact_gn"] + list(DESIGNS)
    rigs = [kinetre.attach(graph, binds, subset=subset, settings=DESIGNS.get(n, SolverSettings(method="exact")))
            for n in names]
    cpu, energy, steps, monotone = ([[] for _ in names] for _ in range(4))
    for i in range(1, len(frames)):
        cur = [frames[i], second[i]][:skeletons]
        for d, rig in enumerate(rigs):
            cpu[d].append(timed_solve(rig, cur, 1 if d == 0 else repeats))
            rep = rig.last_report
            energy[d].append(rep.energy), steps[d].append(rep.iterations)
            monotone[d].append(bool(np.all(np.diff(rep.energies) < 0)))
    for d, name in enumerate(names[1:], 1):
        ms = np.array(cpu[d][5:]) * 1e3  # after warm-up
        rel = np.array(energy[d]) / np.array(energy[0]) - 1.0
        print(json.dumps({
            "bench": "solve_min_of_3", "nodes": nodes, "graph_nodes": graph.node_count, "skeletons": skeletons,
            "subset": subset, "mode": name, "frames": len(ms),
            "cpu_ms_per_frame_median": round(float(np.median(ms)), 3),
            "cpu_ms_per_frame_p95": round(float(np.percentile(ms, 95)), 3),
            "cpu_ms_per_frame_mean": round(float(ms.mean()), 3),
            "steps_mean": round(float(np.mean(steps[d])), 2),
            "energy_vs_exact_median": float(f"{np.median(rel):.2e}"),
            "energy_vs_exact_abs_median": float(f"{np.median(np.abs(rel)):.2e}"),
            "energy_vs_exact_max": float(f"{rel.max():.2e}"),
            "energy_never_rose": all(monotone[d])}), flush=True)


if __name__ == "__main__":
    compare(256, 2)
    compare(512, 2)
    compare(128, 1, subset="right arm")
