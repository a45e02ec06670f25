"""What a live solve's yield costs in pose quality: bench_network's live case offline, every frame cut.

Spot stood up and scaled to the walker as the studio's "fit" does, 256 nodes (253 in the graph), two users each
possessing one leg, the second 7 frames ahead on the CMU walk, twice round the clip (each loop-around is a
jump). Designs, each on its own
rig, solved frame by frame interleaved (the same load on each):

    uncut      Rig.solve without a stop (the offline solve)
    cut_<s>ms  every frame yields (`live_stop.Yield`, the flag always set) after its first accepted step past s ms
               of its thread's CPU: the worst case of the studio's rule, in which a newer frame or the frame's
               lateness (`scene.solve_loop.LATE_S`) always asks it to yield; the next frame goes on from the pose reached

Prints one JSON line per design: thread CPU per frame (median, p99, max), frames that yielded, and E against the
uncut solve of the same frame (E_design / E_uncut - 1: median, p95, max; they are different trajectories).
"""
from __future__ import annotations

import json
import os
import sys
import time
from importlib import resources
from pathlib import Path

import numpy as np

import kinetre
from kinetre.deform.fast.live_stop import Yield
from kinetre.motion.bvh import load_bvh
from kinetre.studio.placement import Placement, standing_mesh

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
SHARES_MS = (5.0, 3.0, 2.0)


def live_case():
    mesh = standing_mesh(kinetre.load_mesh(str(resources.files("kinetre") / "data" / "spot.obj")))
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    walk = [take.frame(i) for i in range(0, len(take), 4)]
    place = Placement.fitted(walk[0], mesh)
    local = [place.to_local(f) for f in walk]
    seq = [[local[k % len(local)], local[(k + 7) % len(local)]] for k in range(2 * len(local))]
    return kinetre.build_graph(mesh, nodes=256, seed=0), seq


def main() -> None:
    graph, seq = live_case()
    designs = {"uncut": None, **{f"cut_{s:g}ms": s / 1000 for s in SHARES_MS}}
    rigs = {name: kinetre.attach(graph, seq[0], subset=["left leg", "right leg"]) for name in designs}
    for rig in rigs.values():
        rig.solve(seq[1])  # a rig's first solve is exact (the warm start), never cut: not counted
    flag = np.ones(1, np.uint8)  # a newer frame always waits
    cpu = {name: [] for name in designs}
    energy = {name: [] for name in designs}
    stopped = dict.fromkeys(designs, 0)
    for frame in seq[2:]:
        for name, share in designs.items():
            start = time.thread_time()
            rigs[name].solve(frame, stop=None if share is None else Yield(flag, start + share))
            cpu[name].append(1000 * (time.thread_time() - start))
            report = rigs[name].last_report
            energy[name].append(report.energy)
            stopped[name] += report.stopped
    uncut = np.array(energy["uncut"])
    for name in designs:
        ms, gap = np.array(cpu[name]), np.array(energy[name]) / uncut - 1
        print(json.dumps({
            "bench": "live_stop", "design": name, "nodes": graph.node_count, "skeletons": 2, "frames": len(ms),
            "timing": "thread CPU per frame, designs interleaved frame by frame",
            "ms_per_frame_median": round(float(np.median(ms)), 3), "ms_per_frame_p99": round(float(np.percentile(ms, 99)), 3),
            "ms_per_frame_max": round(float(ms.max()), 3), "frames_stopped": int(stopped[name]),
            "energy_vs_uncut_median": float(np.median(gap)), "energy_vs_uncut_p95": float(np.percentile(gap, 95)),
            "energy_vs_uncut_max": float(gap.max())}), flush=True)


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
