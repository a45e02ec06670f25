"""50 WebSocket clients for 30 s on 127.0.0.1, malformed messages mixed in.

The server must keep serving everyone, answer every malformed message without dropping the
connection, and count every well-formed frame, including all of those from a client that sends as
fast as it can.
"""
import asyncio
import json
import random
import time

import httpx
import pytest
from studio.conftest import start_server
from studio.studio_ws import StudioClient, frame_message

CLIENTS = 50
SECONDS = 30.0
BAD = ["{", "null", json.dumps({"type": "skeleton", "seq": "one"}), json.dumps({"type": "teleport"}),
       json.dumps({"type": "skeleton", "seq": 1, "t": 0, "model": "kinect20", "positions": [], "tracked": []}),
       "\u00ff" * 50]


@pytest.fixture(scope="module")
def loaded_studio():
    proc, url = start_server(nodes=128)
    yield url, proc
    proc.terminate()
    proc.wait(10)


async def paced_client(url, walk, index, stop_at, possess):
    rng = random.Random(index)
    sent = bad = 0
    async with StudioClient(url) as c:
        if index % 5 == 0:
            await c.send({"type": "subscribe", "skeletons": True})  # a viewer page: sees everybody
        if possess:
            await c.send(frame_message(1, walk[0]))
            sent = 1
            await c.wait(lambda c: c.me() is not None and c.me()["frames"] >= 1, 60)
            await c.send({"type": "fit"})
            await c.send({"type": "possess", "subset": "left leg" if index == 0 else "right leg"})
            await c.wait(lambda c: c.me()["possessing"] or any(m["type"] == "error" for m in c.messages), 60)
            assert c.me()["possessing"], [m for m in c.messages if m["type"] == "error"]
        seq = sent
        while time.monotonic() < stop_at:
            if rng.random() < 0.1:
                await c.send(rng.choice(BAD))
                bad += 1
            else:
                seq += 1
                await c.send(frame_message(seq, walk[seq % len(walk)]))
                sent += 1
            await asyncio.sleep(1 / 30)
        stats = await c.stats(timeout=120)
        return {"sent": sent, "bad": bad, "stats": stats, "transforms": c.transform_count,
                "skeletons": sum(m["type"] == "skeleton" for m in c.messages), "viewer": index % 5 == 0,
                "errors": sum(m["type"] == "error" for m in c.messages)}


async def fast_client(url, walk, stop_at):
    sent = 0
    async with StudioClient(url) as c:
        while time.monotonic() < stop_at:
            for _ in range(50):
                sent += 1
                await c.send(frame_message(sent, walk[sent % len(walk)]))
            await asyncio.sleep(0)  # let the other clients run; no pacing otherwise
        stats = await c.stats(timeout=120)
        return {"sent": sent, "stats": stats, "transforms": c.transform_count}


async def probe(url, stop_at):
    """The server answers plain HTTP throughout the storm."""
    worst = 0.0
    async with httpx.AsyncClient(base_url=url, timeout=30) as http:
        while time.monotonic() < stop_at:
            start = time.monotonic()
            try:
                response = await http.get("/api/state")
            except httpx.RemoteProtocolError:  # an idle keep-alive connection closed as we sent: ask again
                response = await http.get("/api/state")
            assert response.status_code == 200
            worst = max(worst, time.monotonic() - start)
            await asyncio.sleep(1.0)
    return worst


def test_fifty_clients_with_malformed_messages(loaded_studio, walk):
    url, proc = loaded_studio

    async def go():
        stop_at = time.monotonic() + SECONDS
        paced = [paced_client(url, walk, i, stop_at, possess=i < 2) for i in range(CLIENTS - 1)]
        return await asyncio.gather(fast_client(url, walk, stop_at), probe(url, stop_at), *paced)

    fast, worst_http, *paced = asyncio.run(go())
    assert proc.poll() is None  # still running
    # the fast client: every frame counted, in order
    assert fast["sent"] > 1000
    assert fast["stats"]["received"] == fast["sent"] and fast["stats"]["last_seq"] == fast["sent"]
    assert fast["stats"]["malformed"] == 0
    for r in paced:
        assert r["stats"]["received"] == r["sent"]
        assert r["stats"]["malformed"] == r["bad"] and r["errors"] >= 1
    assert sum(r["bad"] for r in paced) > 100
    # the two possessing clients kept the solver busy and every client saw node transforms
    assert all(r["transforms"] >= 5 for r in paced), [r["transforms"] for r in paced]
    assert all((r["skeletons"] > 100) == r["viewer"] for r in paced)
    assert worst_http < 10.0
    print(json.dumps({"fast_frames": fast["sent"], "paced_frames": sum(r["sent"] for r in paced),
                      "malformed": sum(r["bad"] for r in paced), "worst_http_s": round(worst_http, 3),
                      "min_transforms_per_client": min(r["transforms"] for r in paced),
                      "median_transforms_per_client": sorted(r["transforms"] for r in paced)[len(paced) // 2]}))
