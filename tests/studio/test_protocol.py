"""The studio's WebSocket protocol against a real server on 127.0.0.1: possess, solve, release, bad input."""
import asyncio
import base64
import json

import httpx
import numpy as np
from studio.studio_ws import StudioClient, frame_message

from kinetre.skeleton.models import Skeleton


def run(coro):
    return asyncio.run(coro)


def test_a_new_client_gets_welcome_state_and_the_rest_pose(studio):
    async def go():
        async with StudioClient(studio) as c:
            return c.client, c.state, c.transforms

    client, state, (seq, mesh_id, t_source, t_out, m) = run(go())
    assert client.startswith("c")
    assert state["meshes"][0]["name"] == "spot.obj" and mesh_id == state["meshes"][0]["id"]
    assert m.shape == (state["meshes"][0]["nodes"], 4, 4) and 100 <= m.shape[0] <= 150
    np.testing.assert_allclose(m, np.broadcast_to(np.eye(4), m.shape), atol=1e-6)


def test_mesh_payload_holds_the_skinning_data(studio):
    state = httpx.get(studio + "/api/state").json()
    payload = httpx.get(studio + state["meshes"][0]["url"]).json()
    n, v = payload["nodeCount"], payload["vertexCount"]
    positions = np.frombuffer(base64.b64decode(payload["positions"]), "<f4").reshape(v, 3)
    index = np.frombuffer(base64.b64decode(payload["skinIndex"]), "<u2").reshape(v, 4)
    weight = np.frombuffer(base64.b64decode(payload["skinWeight"]), "<f4").reshape(v, 4)
    assert index.max() < n
    np.testing.assert_allclose(weight.sum(axis=1), 1.0, atol=1e-5)
    # the studio stands every mesh on the floor, 1.6 m tall, centred on x = z = 0
    assert abs(positions[:, 1].min()) < 1e-5 and abs(np.ptp(positions[:, 1]) - 1.6) < 1e-4
    assert httpx.get(studio + "/api/mesh/999").status_code == 404


def test_possess_follows_the_user_and_release_returns_to_rest(studio, walk):
    async def go():
        async with StudioClient(studio) as c:
            for i in range(3):
                await c.send(frame_message(i + 1, walk[0]))
            await c.wait(lambda c: c.me() and c.me()["frames"] >= 1)
            await c.send({"type": "fit"})
            await c.send({"type": "possess"})
            await c.wait(lambda c: c.me() and c.me()["possessing"], 60)
            attached = c.me()["attached"]
            # walk on: the legs swing, the solve follows; t of our newest frame comes back with the nodes
            t_last = 0.0
            for i in range(1, 40):
                t_last = 1e12 + i
                await c.send(frame_message(i + 3, walk[i], t=t_last))
                await asyncio.sleep(0.02)
            await c.wait(lambda c: c.transforms[2] == t_last, 60)
            moved = c.matrices().copy()
            await c.send({"type": "release"})
            await c.wait(lambda c: c.me() and not c.me()["possessing"], 60)
            await c.wait(lambda c: np.allclose(c.matrices(), np.eye(4), atol=1e-6), 30)
            return attached, moved

    attached, moved = run(go())
    assert len(attached) >= 1
    nodes = httpx.get(studio + "/api/mesh/1").json()["nodes"]
    g = np.frombuffer(base64.b64decode(nodes), "<f4").reshape(-1, 3)
    displaced = np.einsum("nij,nj->ni", moved[:, :3, :3], g) + moved[:, :3, 3] - g
    assert np.linalg.norm(displaced, axis=1).max() > 0.05  # the walk moved part of the mesh by > 5 cm
    assert np.isfinite(moved).all()


def test_malformed_messages_are_answered_and_the_connection_keeps_working(studio, walk):
    bad = [
        "not json", "[1, 2]", "{}", json.dumps({"type": 3}), json.dumps({"type": "dance"}),
        json.dumps({"type": "skeleton", "seq": 1, "t": 0, "model": "kinect20", "positions": [[0, 0, 0]] * 3,
                    "tracked": [True] * 3}),
        json.dumps({"type": "skeleton", "seq": -4, "t": 0, "model": "kinect20", "positions": [None] * 20,
                    "tracked": [False] * 20}),
        json.dumps({"type": "skeleton", "seq": 1, "t": 0, "model": "horse", "positions": [], "tracked": []}),
        json.dumps({"type": "skeleton", "seq": 1, "t": 0, "model": "kinect20", "positions": [["a", 0, 0]] * 20,
                    "tracked": [True] * 20}),
        json.dumps({"type": "possess", "subset": 42}),
        json.dumps({"type": "place", "scale": -1, "position": [0, 0, 0], "yaw": 0}),
        "x" * 70000,
        b"\x00\xff binary",
    ]

    async def go():
        async with StudioClient(studio) as c:
            for message in bad:
                await c.send(message)
            await c.send(frame_message(5, walk[0]))
            stats = await c.stats()
            errors = [m["message"] for m in c.messages if m["type"] == "error"]
            return stats, errors

    stats, errors = run(go())
    assert stats["malformed"] == len(bad)
    assert stats["received"] == 1 and stats["last_seq"] == 5
    assert errors and all(e.startswith("bad message:") for e in errors)


def test_possess_far_from_the_mesh_is_a_readable_error(studio, walk):
    far = Skeleton(walk[0].model, walk[0].positions + [40.0, 0.0, 0.0], walk[0].tracked)

    async def go():
        async with StudioClient(studio) as c:
            await c.send({"type": "place", "scale": 1.0, "position": [0, 0, 0], "yaw": 0})
            await c.send(frame_message(1, far))
            await c.wait(lambda c: c.me() and c.me()["frames"] >= 1)
            await c.send({"type": "possess"})
            await c.wait(lambda c: any(m["type"] == "error" for m in c.messages), 30)
            return [m["message"] for m in c.messages if m["type"] == "error"], c.me()

    errors, me = run(go())
    assert "cannot possess" in errors[0] and "cm of the mesh" in errors[0]
    assert not me["possessing"]


def test_unknown_subset_is_refused_with_the_known_names(studio, walk):
    async def go():
        async with StudioClient(studio) as c:
            await c.send(frame_message(1, walk[0]))
            await c.wait(lambda c: c.me() and c.me()["frames"] >= 1)
            await c.send({"type": "possess", "subset": "tail"})
            await c.wait(lambda c: any(m["type"] == "error" for m in c.messages), 30)
            return [m["message"] for m in c.messages if m["type"] == "error"][0]

    message = run(go())
    assert "tail" in message and "left arm" in message


def test_a_viewer_with_a_window_never_has_more_unacknowledged_messages(studio, walk):
    async def go():
        async with StudioClient(studio) as driver, StudioClient(studio) as viewer:
            await viewer.send({"type": "subscribe", "skeletons": True, "window": 3})
            await viewer.send({"type": "ack", "received": 3})  # welcome, state, rest pose
            await driver.send(frame_message(1, walk[0]))
            await driver.wait(lambda c: c.me() and c.me()["frames"] >= 1)
            await driver.send({"type": "fit"})
            await driver.send({"type": "possess"})
            await driver.wait(lambda c: c.me()["possessing"], 60)
            for i in range(1, 40):  # a stream of transforms and skeletons the viewer does not acknowledge
                await driver.send(frame_message(i + 1, walk[i]))
                await asyncio.sleep(0.02)
            await asyncio.sleep(1.0)
            stalled = len(viewer.messages) + viewer.transform_count
            await viewer.send({"type": "ack", "received": stalled})
            await viewer.wait(lambda c: len(c.messages) + c.transform_count > stalled, 30)
            await driver.send(frame_message(100, walk[41]))
            await asyncio.sleep(1.0)
            return stalled, len(viewer.messages) + viewer.transform_count

    stalled, resumed = run(go())
    assert stalled <= 3 + 3  # the first three, then at most one window
    assert stalled < resumed <= stalled + 3


def test_tracking_loss_holds_the_last_pose(studio, walk):
    lost = Skeleton(walk[0].model, np.full((20, 3), np.nan), np.zeros(20, bool))

    async def go():
        async with StudioClient(studio) as c:
            await c.send(frame_message(1, walk[0]))
            await c.wait(lambda c: c.me() and c.me()["frames"] >= 1)
            await c.send({"type": "fit"})
            await c.send({"type": "possess"})
            await c.wait(lambda c: c.me()["possessing"], 60)
            await c.send(frame_message(2, walk[20], t=2e12))
            await c.wait(lambda c: c.transforms[2] == 2e12, 60)
            held = c.matrices().copy()
            await c.send(frame_message(3, lost, t=3e12))  # nobody in view
            await c.wait(lambda c: c.transforms[2] == 3e12, 60)
            return held, c.matrices().copy(), c.me()["possessing"]

    held, after, possessing = run(go())
    assert possessing
    assert np.abs(held - np.eye(4)).max() > 0.01  # the pose was not the rest pose
    np.testing.assert_allclose(after, held, atol=1e-6)
