"""A minimal studio WebSocket client for tests and the benchmark (what a capture page does)."""
from __future__ import annotations

import asyncio
import json
import time

import numpy as np
from websockets.asyncio.client import connect

from kinetre.wire.transforms import unpack_transforms


def frame_message(seq: int, skeleton, t: float | None = None, hands=None, blendshapes=None) -> str:
    """A "skeleton" message; `hands` (2, 21, 3) with NaN for a hand not seen, `blendshapes` (52,)."""
    rows = [p.tolist() if ok else None for p, ok in zip(skeleton.positions, skeleton.tracked)]
    msg = {"type": "skeleton", "seq": seq, "t": time.time() * 1000 if t is None else t,
           "model": skeleton.model.name, "positions": rows, "tracked": skeleton.tracked.tolist()}
    if hands is not None:
        msg["hands"] = [h.tolist() if np.isfinite(h).all() else None for h in hands]
    if blendshapes is not None:
        msg["blendshapes"] = np.asarray(blendshapes).tolist()
    return json.dumps(msg)


async def possessed_client(url, walk) -> "StudioClient":
    """A connected client that has sent the walk's first frame, fitted the mesh to it and possesses it."""
    c = StudioClient(url)
    await c.__aenter__()
    await c.send(frame_message(1, walk[0]))
    await c.wait(lambda c: c.me() and c.me()["frames"] >= 1)
    await c.send({"type": "fit"})
    await c.send({"type": "possess"})
    await c.wait(lambda c: c.me() and c.me()["possessing"], 60)
    return c


class StudioClient:
    """Connects, remembers the newest state/transforms, and waits for conditions on them."""

    def __init__(self, url: str, token: str | None = None, resume: str | None = None):
        query = "&".join(f"{k}={v}" for k, v in (("token", token), ("resume", resume)) if v)
        self.url = url.replace("http://", "ws://") + "/ws" + (f"?{query}" if query else "")
        self.client = ""
        self.resume = ""  # "client.token": what a reconnect passes to come back as this client
        self.state: dict | None = None
        self.transforms: tuple | None = None  # (seq, mesh_id, t_source, t_out, matrices)
        self.mesh_transforms: dict[int, tuple] = {}  # the newest transforms of each mesh, by mesh id
        self.transform_count = 0
        self.messages: list[dict] = []
        self.blocks: list[tuple[float, bytes]] = []  # (t_source, raw block) per transform block
        self.arrivals: list[tuple[float, float]] = []  # (t_source, time received) per transform block
        self._ws = None
        self._reader = None
        self._changed = asyncio.Event()
        self.connect_timeout = 30.0

    async def __aenter__(self):
        self._ws = await connect(self.url, max_size=1 << 22)
        self._reader = asyncio.get_running_loop().create_task(self._read())
        await self.wait(lambda c: c.client and c.state is not None and c.transforms is not None, self.connect_timeout)
        return self

    async def __aexit__(self, *exc):
        self._reader.cancel()
        await self._ws.close()

    async def drop(self) -> None:
        """Lose the connection as a network would: no closing handshake."""
        self._reader.cancel()
        self._ws.transport.abort()

    async def _read(self):
        async for data in self._ws:
            now = time.time() * 1000
            if isinstance(data, bytes):
                self.transforms = unpack_transforms(data)
                self.mesh_transforms[self.transforms[1]] = self.transforms
                self.transform_count += 1
                self.arrivals.append((self.transforms[2], now))
                self.blocks.append((self.transforms[2], data))
            else:
                msg = json.loads(data)
                self.messages.append(msg)
                if msg["type"] == "welcome":
                    self.client, self.resume = msg["client"], msg["resume"]
                elif msg["type"] == "state":
                    self.state = msg
            self._changed.set()

    async def send(self, message) -> None:
        await self._ws.send(message if isinstance(message, (str, bytes)) else json.dumps(message))

    async def wait(self, predicate, timeout: float = 30.0):
        deadline = time.monotonic() + timeout
        while not predicate(self):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError("condition not met; errors: " + json.dumps([m for m in self.messages if m["type"] == "error"][-3:]) + "; last messages: " + json.dumps(self.messages[-3:])[:800])
            self._changed.clear()
            try:
                await asyncio.wait_for(self._changed.wait(), min(remaining, 0.5))
            except asyncio.TimeoutError:
                pass

    async def perform(self, frames, first_seq: int, until, watcher: "StudioClient | None" = None,
                      timeout: float = 120.0, fps: float = 30.0) -> None:
        """Send `frames` (cycling) as a camera would, one every 1/fps s, until `until(watcher)` holds: the scene
        merges frames that arrive faster than it solves (the newest wins), so a burst of frames can yield a
        single solve, and a test waiting for several solves must keep performing while it waits."""
        watcher = watcher or self
        deadline = time.monotonic() + timeout
        k = 0
        while not until(watcher):
            if time.monotonic() > deadline:
                raise TimeoutError("condition not met while performing; last messages: "
                                   + json.dumps(watcher.messages[-3:])[:800])
            await self.send(frame_message(first_seq + k, frames[k % len(frames)]))
            k += 1
            await asyncio.sleep(1.0 / fps)

    def me(self) -> dict | None:
        for u in (self.state or {}).get("users", []):
            if u["client"] == self.client:
                return u
        return None

    async def stats(self, timeout: float = 30.0) -> dict:
        count = len(self.messages)
        await self.send({"type": "stats"})
        await self.wait(lambda c: any(m["type"] == "stats" for m in c.messages[count:]), timeout)
        return [m for m in self.messages[count:] if m["type"] == "stats"][-1]

    def matrices(self) -> np.ndarray:
        return self.transforms[4]
