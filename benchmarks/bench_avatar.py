"""Avatar retargeting (Algorithm 1): ms per frame of `retarget` on the CMU walk (524 frames, 120 fps) for each
humanoid in ../shared/data/avatars.

Prints one JSON object per line: {"bench": "retarget", "avatar": ..., "mode": "batch", ...} for a whole take
in one call (what `kinetre avatar` does) and {"mode": "stream", ...} for one frame per call with carried
state (a live source); target ≤ 0.1 ms per frame. Also the numpy skinning of one frame (all primitives), for
scale: the studio skins on the GPU. Best of several repeats, wall time and this process's CPU time (the
machine is shared: the load average is printed with the figures).
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from kinetre.avatar.bonemap import map_bones
from kinetre.avatar.load import load_avatar
from kinetre.avatar.retarget import RetargetState, plan_retarget, retarget
from kinetre.avatar.skin import skin_avatar
from kinetre.motion.bvh import load_bvh

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
AVATARS = ("RiggedFigure", "CesiumMan", "robot_quaternius")


def best(f, repeats, clock=time.perf_counter):
    out = float("inf")
    for _ in range(repeats):
        t0 = clock()
        f()
        out = min(out, clock() - t0)
    return out


def main() -> None:
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    pos, tracked = take.positions, take.tracked
    for name in AVATARS:
        avatar = load_avatar(DATA / "avatars" / f"{name}.glb")
        plan = plan_retarget(avatar, map_bones(avatar))
        retarget(plan, pos, tracked)
        batch = best(lambda: retarget(plan, pos, tracked), 7) / len(take)
        # CPU time of this process: what a frame costs, less inflated than wall time on a busy machine
        batch_cpu = best(lambda: retarget(plan, pos, tracked), 7, time.process_time) / len(take)
        state = RetargetState()
        frames = 120

        def stream():
            for t in range(frames):
                retarget(plan, pos[t:t + 1], tracked[t:t + 1], state)
        one = best(stream, 3) / frames
        world = retarget(plan, pos[:1], tracked[:1]).world
        skin = best(lambda: skin_avatar(avatar, world), 5)
        common = {"bench": "retarget", "avatar": name, "joints": len(avatar.joints),
                  "vertices": avatar.vertex_count, "frames": len(take)}
        print(json.dumps({**common, "mode": "batch", "ms_per_frame": round(batch * 1e3, 4),
                          "cpu_ms_per_frame": round(batch_cpu * 1e3, 4), "target_ms": 0.1,
                          "cpu_within_target": batch_cpu * 1e3 <= 0.1, "load_average": round(os.getloadavg()[0], 1)}),
              flush=True)
        print(json.dumps({**common, "mode": "stream", "ms_per_frame": round(one * 1e3, 4),
                          "numpy_skin_ms_per_frame": round(skin * 1e3, 3)}), flush=True)


if __name__ == "__main__":
    main()
