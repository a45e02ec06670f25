"""Issue 9's local/global solver and its variants against the default, timed as bench_core's solve records
(`bench_core.replay`): per frame each design solves from its own warm state three times, the least CPU time of
the solving thread counts; the designs take turns frame by frame, so a shared machine's load falls on all of
them alike.

The frames are bench_core's (the walk at 30 fps, a second skeleton 3 cm aside, 256 and 512 nodes), plus one arm
possessing the body (128 nodes, the hard case for agreement). Prints one JSON object per line. Run on one core:
OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

import kinetre
from kinetre.deform.local_global import LocalGlobalSettings
from kinetre.deform.solver import SolverSettings

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_core import capsule_body, replay, walk_frames  # noqa: E402

DESIGNS = {
    "exact_gn": SolverSettings(method="exact"),
    "pcg_default": SolverSettings(),
    # by default one local/global iteration, then the PCG loop; "alone" runs them until the gain test (or a
    # stall) ends them
    "local_global": SolverSettings(method="local_global"),
    "local_global_two_then_pcg": SolverSettings(method="local_global",
                                                local_global=LocalGlobalSettings(then_gauss_newton=2)),
    "local_global_alone": SolverSettings(method="local_global", local_global=LocalGlobalSettings(then_gauss_newton=0)),
    "local_global_alone_tight": SolverSettings(method="local_global", local_global=LocalGlobalSettings(
        then_gauss_newton=0, gain_tolerance=1e-6, max_iterations=40)),
}


def compare(nodes, skeletons, subset=None, skip=5):
    frames, _ = walk_frames()
    graph = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=nodes)
    runs, _ = replay(graph, skeletons, DESIGNS, subset)
    for name, run in runs.items():
        if name == "exact_gn":
            continue
        ms = run["cpu"][skip:] * 1e3
        rel = run["energy"] / runs["exact_gn"]["energy"] - 1.0
        print(json.dumps({
            "bench": "solve_min_of_3", "nodes": nodes, "graph_nodes": graph.node_count, "skeletons": skeletons,
            "subset": subset, "mode": name, "frames": len(ms),
            "cpu_ms_per_frame_median": round(float(np.median(ms)), 3),
            "cpu_ms_per_frame_p95": round(float(np.percentile(ms, 95)), 3),
            "cpu_ms_per_frame_mean": round(float(ms.mean()), 3),
            "steps_mean": round(float(np.mean(run["steps"])), 2),
            "energy_vs_exact_median": float(f"{np.median(rel):.2e}"),
            "energy_vs_exact_abs_median": float(f"{np.median(np.abs(rel)):.2e}"),
            "energy_vs_exact_max": float(f"{rel.max():.2e}"),
            "energy_never_rose": bool(run["monotone"].all())}), flush=True)


if __name__ == "__main__":
    compare(256, 2)
    compare(512, 2)
    compare(128, 1, subset="right arm")
