"""The networked studio under load, the embedded hub and NATS side by side, plus a 512-node solve.

Load: 20 capture clients sending Kinect-20 frames at 30 Hz (two of them possess the mesh, left and right
leg), 100 viewers receiving the node transforms, one scene with a 256-node rig. All 120 WebSocket clients
live in this process, one event loop: each is a `websockets` sans-I/O protocol driven from its socket's
callback, and a viewer timestamps a transform block in the callback that completes it (no task or queue per
message, so this generator's own delay is as small as one process can make it; real viewers would be on
other machines). Every sample counts: nothing is excluded. The generator's start-up objects are frozen out
of its garbage collector (`gc.freeze`), as the studio's are.

    embedded   one studio process: the embedded hub, the scene, its solve worker process
    nats       nats-server + `kinetre scene` + `kinetre studio --nats --remote-scene` (the gateway)

Prints JSON lines:
  {"bench": "network_load", "bus": ..., "latency_median_ms", "latency_p99_ms": capture timestamp → viewer
   receipt of the transforms solved from it, "solve_hz": distinct solved frames per second at a viewer,
   "dropped_by_policy": {...}, "lost": {...}, "rss_mb": {process: [start, end]}, "http_worst_ms": ...}
  {"bench": "network_serving_512", ...}  the embedded studio while a 512-node rig solves: /api/state
   answer times and the solve rate.
"""
from __future__ import annotations

import argparse
import asyncio
import gc
import json
import os
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / ".." / "shared" / "data"
sys.path.insert(0, str(ROOT / "tests"))

from studio.conftest import start_server  # noqa: E402
from studio.nats_server import ROOMS, NatsServer  # noqa: E402
from studio.studio_ws import frame_message  # noqa: E402
from websockets.client import ClientProtocol  # noqa: E402
from websockets.extensions.permessage_deflate import enable_client_permessage_deflate  # noqa: E402
from websockets.frames import Opcode  # noqa: E402
from websockets.http11 import Response  # noqa: E402
from websockets.uri import parse_uri  # noqa: E402

from kinetre.motion.bvh import load_bvh  # noqa: E402

CAPTURE, VIEWERS, HZ, NODES = 20, 100, 30.0, 256
SECONDS = float(os.environ.get("KINETRE_BENCH_NETWORK_SECONDS", 20))
HEADER = struct.Struct("<4sIIIdd")


def walk_frames() -> list[tuple[str, str]]:
    """The CMU walk at 30 Hz as skeleton messages encoded once, split around their "seq" and "t" (the
    generator fills those in per send, so what is measured is the servers, not JSON encoding here)."""
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    marker = '"seq": 0, "t": 0.0'
    return [tuple(frame_message(0, take.frame(i), t=0.0).split(marker)) for i in range(0, len(take), 4)]


def tree(pid: int) -> list[int]:
    """A process and its descendants (the solve worker)."""
    found, pids = [], [pid]
    while pids:
        p = pids.pop()
        found.append(p)
        try:
            for task in Path(f"/proc/{p}/task").iterdir():
                pids += [int(c) for c in (task / "children").read_text().split()]
        except (FileNotFoundError, ProcessLookupError):
            pass
    return found


def rss_mb(pid: int) -> float:
    """Resident memory of a process and its children (the solve worker), MB."""
    total = 0.0
    for p in tree(pid):
        try:
            for line in Path(f"/proc/{p}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1]) / 1024
        except (FileNotFoundError, ProcessLookupError):
            pass
    return round(total, 1)


def schedstat(pid: int) -> tuple[float, float]:
    """(CPU seconds, seconds spent runnable but waiting for a core) of all threads of one process."""
    cpu = wait = 0.0
    try:
        for task in Path(f"/proc/{pid}/task").iterdir():
            fields = (task / "schedstat").read_text().split()
            cpu, wait = cpu + int(fields[0]) / 1e9, wait + int(fields[1]) / 1e9
    except (FileNotFoundError, ProcessLookupError):
        pass
    return cpu, wait


def cpu_use(pids: dict) -> dict:
    """{name: (CPU s, waiting for a CPU s)} so far of this process (the load generator), of every named
    process and, separately, of its children (e.g. the solve worker)."""
    use = {"load_generator": schedstat(os.getpid())}
    for name, pid in pids.items():
        use[name] = schedstat(pid)
        children = [schedstat(p) for p in tree(pid)[1:]]
        if children:
            use[name + "_children"] = tuple(map(sum, zip(*children)))
    return use


class Client(asyncio.Protocol):
    """One WebSocket client on websockets' sans-I/O protocol, driven straight from the event loop's socket
    callback: no task or queue per message, and a transform block is timestamped in the callback that
    completes it (the earliest this process can know of it; a page or a viewer on another machine would not
    share one process with 119 other clients). Offers permessage-deflate as browsers do; the server decides.
    """

    def __init__(self, url: str):
        self.ws = ClientProtocol(parse_uri(url), extensions=enable_client_permessage_deflate(None),
                                 max_size=1 << 22)
        self.transport = None
        self.stats = None
        self.opened = asyncio.get_running_loop().create_future()

    async def open(self, timeout=60.0):
        uri = self.ws.uri
        await asyncio.get_running_loop().create_connection(lambda: self, uri.host, uri.port)
        await asyncio.wait_for(self.opened, timeout)

    def connection_made(self, transport):
        self.transport = transport
        self.ws.send_request(self.ws.connect())
        self.flush()

    def data_received(self, data):
        now = time.time() * 1000
        self.ws.receive_data(data)
        for event in self.ws.events_received():
            if isinstance(event, Response):
                if self.ws.handshake_exc is not None:
                    self.opened.set_exception(self.ws.handshake_exc)
                else:
                    self.opened.set_result(None)
            elif event.opcode is Opcode.BINARY:
                self.block(event.data, now)
            elif event.opcode is Opcode.TEXT:
                self.text(event.data.decode())
        self.flush()

    def flush(self):
        for chunk in self.ws.data_to_send():
            if chunk:
                self.transport.write(chunk)

    def send(self, text: str):
        self.ws.send_text(text.encode())
        self.flush()

    def close(self):
        if self.transport is not None:
            self.transport.close()

    def block(self, data: bytes, now: float):
        pass

    def text(self, data: str):
        if data.startswith('{"type": "stats"'):
            self.stats = json.loads(data)

    async def ask_stats(self, timeout=30.0):
        self.stats = None
        self.send('{"type": "stats"}')
        deadline = time.monotonic() + timeout
        while self.stats is None and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        return self.stats


class Viewer(Client):
    """A page that only watches: records (seq, t_source, received ms, t_out) per transform block."""

    def __init__(self, url: str):
        super().__init__(url)
        self.blocks = []

    def block(self, data, now):
        _, seq, _, _, t_source, t_out = HEADER.unpack_from(data)
        self.blocks.append((seq, t_source, now, t_out))


class Capture(Client):
    """A page with a camera: frames at 30 Hz on an absolute schedule; the first two possess the mesh."""

    def __init__(self, url, frames: list[tuple[str, str]], index):
        super().__init__(url)
        self.frames, self.index, self.sent, self.stamps, self.seq = frames, index, 0, [], 0
        self.received_blocks = 0
        self.state = None

    def block(self, data, now):
        self.received_blocks += 1

    def text(self, data):
        if data.startswith('{"type": "state"'):
            self.state = json.loads(data)
        else:
            super().text(data)

    def frame(self, k):
        self.seq += 1
        t = time.time() * 1000
        head, tail = self.frames[(k + 7 * self.index) % len(self.frames)]
        self.send(f'{head}"seq": {self.seq}, "t": {t!r}{tail}')
        self.sent += 1
        if self.index < 2:
            self.stamps.append(t)

    async def stream(self, until: float):
        start, k = time.monotonic(), 0
        while time.monotonic() < until:
            self.frame(k)
            k += 1
            await asyncio.sleep(max(0.0, start + k / HZ - time.monotonic()))


async def http_probe(base: str, token: str | None, until: float) -> list[float]:
    ms = []
    async with httpx.AsyncClient(base_url=base, params={"token": token} if token else None, timeout=30) as http:
        while time.monotonic() < until:
            t = time.perf_counter()
            assert (await http.get("/api/state")).status_code == 200
            ms.append(1000 * (time.perf_counter() - t))
            await asyncio.sleep(0.5)
    return ms


async def wait_possessing(cap: Capture, timeout=60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        users = (cap.state or {}).get("users", [])
        mine = [u for u in users if u["possessing"]]
        if len(mine) >= 2:
            return
        await asyncio.sleep(0.1)
    raise RuntimeError(f"the two capture clients could not possess: {cap.state}")


async def load(base: str, token: str | None, frames, pids: dict, captures=CAPTURE, viewers=VIEWERS,
               seconds=SECONDS) -> dict:
    ws_url = base.replace("http://", "ws://") + "/ws" + (f"?token={token}" if token else "")
    caps = [Capture(ws_url, frames, i) for i in range(captures)]
    views = [Viewer(ws_url) for _ in range(viewers)]
    loop = asyncio.get_running_loop()
    await asyncio.gather(*(c.open() for c in caps + views))
    # the two possessors: a first frame, fit, possess a leg each
    for cap in caps[:2]:
        cap.frame(0)
    await asyncio.sleep(1.0)
    caps[0].send('{"type": "fit"}')
    caps[0].send('{"type": "possess", "subset": "left leg"}')
    caps[1].send('{"type": "possess", "subset": "right leg"}')
    await wait_possessing(caps[0])
    await asyncio.sleep(1.0)
    gc.collect()
    gc.freeze()  # this generator's own full collections would stall every client's receipt
    rss_start = {name: rss_mb(pid) for name, pid in pids.items()}
    cpu_start = cpu_use(pids)
    t0 = time.monotonic()
    until = t0 + seconds
    mark = [len(v.blocks) for v in views]
    sent_before, blocks_before = sum(c.sent for c in caps), sum(c.received_blocks for c in caps)
    probe = loop.create_task(http_probe(base, token, until))
    await asyncio.gather(*(c.stream(until) for c in caps))
    http_ms = await probe
    window = time.monotonic() - t0
    cpu_end = cpu_use(pids)
    frames_in_window = sum(c.sent for c in caps) - sent_before
    blocks_in_window = sum(len(v.blocks) - m for v, m in zip(views, mark)) + sum(c.received_blocks for c in caps) \
        - blocks_before
    await asyncio.sleep(2.0)  # drain: everything in flight arrives
    rss_end = {name: rss_mb(pid) for name, pid in pids.items()}
    async with httpx.AsyncClient(base_url=base, params={"token": token} if token else None) as http:
        state = (await http.get("/api/state")).json()
    cap_stats = await asyncio.gather(*(c.ask_stats() for c in caps))
    view_stats = await asyncio.gather(*(v.ask_stats() for v in views))
    for client in caps + views:
        client.close()

    stamps = set(caps[0].stamps) | set(caps[1].stamps)
    latency, solving, delivery, solved = [], [], [], set()
    for v, m in zip(views, mark):
        for seq, t_source, got, t_out in v.blocks[m:]:
            if t_source in stamps:
                latency.append(got - t_source)
                solving.append(t_out - t_source)
                delivery.append(got - t_out)
                if v is views[0]:
                    solved.add(seq)
    lat = np.asarray(latency if latency else [float("nan")])

    def median_p99(ms):
        ms = np.asarray(ms if ms else [float("nan")])
        return [round(float(np.median(ms)), 1), round(float(np.percentile(ms, 99)), 1)]
    received = sum(s["received"] for s in cap_stats)
    sent = sum(c.sent for c in caps)
    merged, late = state["dropped"]["merged"], state["dropped"]["late"]
    return {
        "captures": captures, "viewers": viewers, "nodes": state["meshes"][0]["nodes"], "seconds": seconds,
        "latency_median_ms": round(float(np.median(lat)), 2), "latency_p99_ms": round(float(np.percentile(lat, 99)), 2),
        "latency_samples": int(lat.size),
        # the same latency in two parts, at the scene's publish time t_out: capture → solved and published
        # (waiting for the scene, the solve) and published → viewer (the fan-out, and this generator's own delay)
        "latency_split_ms": {"capture_to_published": median_p99(solving), "published_to_viewer": median_p99(delivery)},
        "solve_hz": round(len(solved) / seconds, 1), "solve_ms_median": state["solve_ms"],
        "solve_cpu_ms_median": state.get("solve_cpu_ms"), "solve_cpu_ms_p99": state.get("solve_cpu_ms_p99"),
        # solves that yielded to a newer frame after a Gauss-Newton step (the scene's last 600 solves: p99)
        "solves_stopped": state.get("solves_stopped"),
        "frames_sent": sent,
        "dropped_by_policy": {"skeletons_merged_at_scene": merged, "skeletons_late": late,
                              "transforms_skipped_for_slow_viewers": sum(s["transforms_skipped"] for s in view_stats)},
        "lost": {"capture_to_server": sent - received,
                 "server_to_scene": received - state["skeleton_frames"],
                 "server_to_viewers": sum(s["transforms_sent"] for s in view_stats) - sum(len(v.blocks) for v in views),
                 "bus_sequence_gaps": state.get("bus", {}).get("gaps", 0)},
        "rss_mb": {name: [rss_start[name], rss_end[name]] for name in pids},
        "http_median_ms": round(float(np.median(http_ms)), 1), "http_worst_ms": round(max(http_ms), 1),
        # share of one core over the window (200 = both cores of this machine)
        "cpu_percent": {name: round(100 * (cpu_end[name][0] - cpu_start.get(name, (0, 0))[0]) / window, 1)
                        for name in cpu_end},
        # runnable but not running: the share of the window each process waited for a core (the kernel's
        # schedstat run delay, summed over threads)
        "waiting_for_cpu_percent": {name: round(100 * (cpu_end[name][1] - cpu_start.get(name, (0, 0))[1]) / window, 1)
                                    for name in cpu_end},
        # what the servers handled in the window: WebSocket messages in (skeleton frames) and out (transform
        # blocks received by the 120 clients)
        "messages_in_window": {"skeleton_frames": frames_in_window, "transform_blocks": blocks_in_window},
        "load_average_1min": round(os.getloadavg()[0], 2),
    }


def run_loop(coro):
    """uvloop when installed (as uvicorn uses): the generator's own event-loop cost is part of what it adds."""
    try:
        import uvloop
    except ImportError:
        return asyncio.run(coro)
    return uvloop.run(coro)


def run_embedded(frames, shape) -> dict:
    proc, url = start_server(nodes=NODES)
    try:
        return {"bench": "network_load", "bus": "embedded",
                **run_loop(load(url, None, frames, {"studio": proc.pid}, **shape))}
    finally:
        proc.terminate()
        proc.wait(10)


def run_nats(frames, shape) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="kinetre-bench-net-"))
    with NatsServer() as nats:
        log = open(tmp / "scene.log", "ab")
        scene = subprocess.Popen([sys.executable, "-m", "kinetre.cli", "scene", "--nats", nats.url, "--room", "a",
                                  "--token", ROOMS["a"], "--nodes", str(NODES)],
                                 stdout=log, stderr=subprocess.STDOUT, env=dict(os.environ, PYTHONUNBUFFERED="1"))
        try:
            deadline = time.monotonic() + 120
            while "Kinetre scene" not in (tmp / "scene.log").read_text():
                if scene.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError((tmp / "scene.log").read_text()[-2000:])
                time.sleep(0.2)
            proc, url = start_server(nats=nats.url, room="a", token=ROOMS["a"], remote_scene=True)
            try:
                pids = {"studio": proc.pid, "scene": scene.pid, "nats-server": nats.proc.pid}
                return {"bench": "network_load", "bus": "nats", **run_loop(load(url, ROOMS["a"], frames, pids,
                                                                                 **shape))}
            finally:
                proc.terminate()
                proc.wait(10)
        finally:
            scene.terminate()
            scene.wait(10)


def run_serving_512(frames, shape) -> dict:
    """The embedded studio while a 512-node rig solves: does it keep answering?"""
    proc, url = start_server(nodes=512)
    try:
        result = run_loop(load(url, None, frames, {"studio": proc.pid}, captures=2, viewers=20, seconds=10))
    finally:
        proc.terminate()
        proc.wait(10)
    keep = ("nodes", "solve_hz", "solve_ms_median", "solve_cpu_ms_median", "solve_cpu_ms_p99", "solves_stopped",
            "cpu_percent", "latency_median_ms", "latency_p99_ms", "http_median_ms",
            "http_worst_ms")
    return {"bench": "network_serving_512", "captures": 2, "viewers": 20, **{k: result[k] for k in keep}}


RUNS = {"embedded": run_embedded, "nats": run_nats, "serving_512": run_serving_512}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--captures", type=int, default=CAPTURE, help=f"capture clients (default {CAPTURE})")
    ap.add_argument("--viewers", type=int, default=VIEWERS, help=f"viewers (default {VIEWERS})")
    ap.add_argument("--seconds", type=float, default=SECONDS, help=f"measured window (default {SECONDS:g})")
    ap.add_argument("--runs", default=os.environ.get("KINETRE_BENCH_NETWORK_RUNS", ",".join(RUNS)),
                    help=f"comma-separated subset of {', '.join(RUNS)}")
    args = ap.parse_args()
    frames = walk_frames()
    shape = {"captures": args.captures, "viewers": args.viewers, "seconds": args.seconds}
    for name in args.runs.split(","):
        print(json.dumps(RUNS[name](frames, shape)), flush=True)


if __name__ == "__main__":
    main()
