"""Studio latency and frame rate: skeleton frame in → node transforms out, and the page in a browser.

Prints JSON lines:
  {"bench": "studio_scene_latency", ...}  in process: hub publish of two users' frames → transforms published
                                           (the solve plus everything the studio adds), 256 nodes, two users
  {"bench": "studio_ws_latency", ...}     over WebSocket on 127.0.0.1: client frame timestamp → transform
                                           block received by that client (adds JSON, framing, the event loop)
  {"bench": "studio_browser_fps", ...}    the page in Debian's Chromium (SwiftShader, no GPU) with the sample
                                           motion playing: frames per second and ms per frame without rendering
"""
from __future__ import annotations

import asyncio
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / ".." / "shared" / "data"
sys.path.insert(0, str(ROOT / "tests"))

from studio.conftest import start_server  # noqa: E402
from studio.studio_ws import StudioClient, frame_message  # noqa: E402

from kinetre.motion.bvh import load_bvh  # noqa: E402
from kinetre.studio.channels import Frame, Hub  # noqa: E402
from kinetre.studio.meshes import data_path, prepare_mesh  # noqa: E402
from kinetre.studio.protocol import SkeletonFrame, skeleton_json  # noqa: E402
from kinetre.studio.scene import Scene  # noqa: E402
from kinetre.studio.subjects import TRANSFORMS  # noqa: E402

NODES = 256
FRAMES = 120
WARM_UP = 10  # frames solved before the timed ones (the solver's first frames load its kernels)


def walk_frames() -> list:
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    return [take.frame(i) for i in range(0, len(take), 4)]


def stats(ms: list[float]) -> dict:
    a = np.asarray(ms)
    return {"median_ms": round(float(np.median(a)), 3), "p95_ms": round(float(np.percentile(a, 95)), 3),
            "frames": int(a.size)}


async def scene_latency(frames) -> dict:
    mesh, graph = prepare_mesh(str(data_path("spot.obj")), NODES)
    hub = Hub()
    scene = Scene(hub, mesh, graph, "spot.obj")
    runner = asyncio.get_running_loop().create_task(scene.run())
    out = hub.subscribe(TRANSFORMS)

    def publish(client, seq, skeleton, t=None):
        t = time.time() * 1000 if t is None else t
        hub.publish(Frame(f"kinetre.skeleton.{client}", seq, t, skeleton_json(client, seq, t, skeleton),
                          SkeletonFrame(seq, t, skeleton)))
        return t

    # the scene subscribes when its task starts, and fit and possess need a frame of each user: the first
    # frame again (a newer seq each time) until the scene has both
    seq, deadline = 0, time.monotonic() + 30
    while not all(c in scene.users and scene.users[c].latest is not None for c in ("a", "b")):
        if time.monotonic() > deadline:
            raise RuntimeError("the scene saw no frame of both users within 30 s")
        seq += 1
        for client in ("a", "b"):
            publish(client, seq, frames[0])
        await asyncio.sleep(0.01)
    scene.fit("a")
    await scene.possess("a", "left leg")
    await scene.possess("b", "right leg")
    while out.poll() is not None:
        pass
    total, solve = [], []
    for i in range(WARM_UP + FRAMES):
        skeleton = frames[1 + i % (len(frames) - 1)]
        start = time.perf_counter()
        # both users' frames carry one capture time (a block is stamped with the newest it used)
        t = publish("a", seq + 1 + i, skeleton)
        publish("b", seq + 1 + i, skeleton, t)
        while True:
            # the first solves may compile the solver's kernels (a cold numba cache): minutes on a busy machine
            frame = await out.next(timeout=300)
            if frame is None:
                raise RuntimeError(f"no transforms within 300 s: {scene.state()}")
            if frame.t >= t:
                break
        if i >= WARM_UP:
            total.append(1000 * (time.perf_counter() - start))
            solve.append(scene.meshes.first.solve_ms[-1])
        await asyncio.sleep(1 / 30)
    runner.cancel()
    added = [a - b for a, b in zip(total, solve)]  # what the studio adds to the solve itself
    return {"bench": "studio_scene_latency", "nodes": graph.node_count, "users": 2, **stats(total),
            "solve_median_ms": round(float(np.median(solve)), 3),
            "added_median_ms": round(float(np.median(added)), 3),
            "added_p95_ms": round(float(np.percentile(added, 95)), 3)}


async def ws_latency(url, frames) -> dict:
    async with StudioClient(url) as a, StudioClient(url) as b:
        for c in (a, b):
            await c.send(frame_message(1, frames[0]))
            await c.wait(lambda c: c.me() is not None and c.me()["frames"] >= 1, 60)
        await a.send({"type": "fit"})
        await a.send({"type": "possess", "subset": "left leg"})
        await a.wait(lambda c: c.me()["possessing"], 60)
        await b.send({"type": "possess", "subset": "right leg"})
        await b.wait(lambda c: c.me()["possessing"], 60)
        a.arrivals.clear()
        sent = []
        for i in range(FRAMES):
            skeleton = frames[1 + i % (len(frames) - 1)]
            t = time.time() * 1000
            sent.append(t)
            await a.send(frame_message(i + 2, skeleton, t=t))
            await b.send(frame_message(i + 2, skeleton, t=t + 0.001))
            await asyncio.sleep(1 / 30)
        await asyncio.sleep(1.0)
        # each block names the newest frame it used; latency = arrival − that frame's send time
        ms = [arrived - t_source for t_source, arrived in a.arrivals if t_source >= sent[0]]
        solved = len({round(t) for t, _ in a.arrivals if t >= sent[0]})
    return {"bench": "studio_ws_latency", "nodes": NODES, "users": 2, **stats(ms),
            "frames_sent": FRAMES, "frames_solved": solved}


def browser_fps(url) -> dict:
    driver = ROOT / "tests" / "e2e" / "driver.mjs"
    config = {"scenario": "perf", "url": url + "/", "video": str(DATA / "video" / "pose_1_320x240_30fps.y4m"),
              "artifacts": str(ROOT / "tests" / "e2e" / "artifacts"), "wait": 10000}
    out = subprocess.run(["node", str(driver), json.dumps(config)], capture_output=True, text=True, timeout=300)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if not result.get("ok"):
        raise RuntimeError(result.get("error"))
    return {"bench": "studio_browser_fps", "renderer": "SwiftShader (no GPU)", **result["perf"]}


def main() -> None:
    frames = walk_frames()
    print(json.dumps(asyncio.run(scene_latency(frames))), flush=True)
    proc, url = start_server(nodes=NODES)
    try:
        print(json.dumps(asyncio.run(ws_latency(url, frames))), flush=True)
    finally:
        proc.terminate()
        proc.wait(10)
    proc, url = start_server(nodes=128, sample_motion=True)
    try:
        print(json.dumps(browser_fps(url)), flush=True)
    finally:
        proc.terminate()
        proc.wait(10)


if __name__ == "__main__":
    main()
