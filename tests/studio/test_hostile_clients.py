"""A shared scene under hostile and careless clients: every scene command's numbers are held to physical bounds
(refused with an error naming the field), and a randomized barrage of valid and invalid commands from several
clients leaves the scene solving, its transforms still flowing to a passive viewer."""
from __future__ import annotations

import asyncio
import json
import math
import random

import numpy as np
import pytest

from kinetre.studio.protocol import (MAX_MESH, ROOM, SCALE_RANGE, ProtocolError, check_placement, parse_frame,
                                     parse_mesh, parse_place)
from studio.conftest import start_server
from studio.studio_ws import StudioClient, frame_message


@pytest.mark.parametrize("field, msg", [
    ("scale", {"scale": 1e308}), ("scale", {"scale": SCALE_RANGE[0] / 2}), ("scale", {"scale": SCALE_RANGE[1] * 2}),
    ("scale", {"scale": 0}), ("scale", {"scale": -1.0}), ("scale", {"scale": float("nan")}),
    ("position", {"position": [0.0, 0.0, ROOM * 2]}), ("position", {"position": [1e308, 0, 0]}),
    ("position", {"position": [float("inf"), 0, 0]}), ("yaw", {"yaw": 7.0}), ("yaw", {"yaw": float("-inf")})])
def test_a_placement_out_of_bounds_is_refused_naming_its_field(field, msg):
    with pytest.raises(ProtocolError, match=f"^{field} must be"):
        parse_place({"type": "place", **msg})


def test_a_placement_on_the_bounds_is_accepted():
    for scale in SCALE_RANGE:
        assert parse_place({"scale": scale, "position": [ROOM, -ROOM, 0], "yaw": -2 * math.pi}) == \
            (scale, [ROOM, -ROOM, 0], -2 * math.pi)
    assert check_placement(1, [0, 0, 0], 0) == (1.0, (0.0, 0.0, 0.0), 0.0)


def test_joints_hands_and_mesh_ids_outside_their_bounds_are_refused(walk):
    msg = json.loads(frame_message(1, walk[0]))
    parse_frame(msg)
    far = json.loads(json.dumps(msg))
    far["positions"][3] = [0.0, ROOM * 3, 0.0]
    with pytest.raises(ProtocolError, match="joint 3 of 'positions' lies outside the room"):
        parse_frame(far)
    hands = json.loads(json.dumps(msg))
    hands["hands"] = [[[0.0, 0.0, 1e9]] * 21, None]
    with pytest.raises(ProtocolError, match="the left hand"):
        parse_frame(hands)
    assert parse_mesh({"mesh": MAX_MESH}) == MAX_MESH
    with pytest.raises(ProtocolError, match="'mesh' must be"):
        parse_mesh({"mesh": MAX_MESH + 1})


def barrage(rng: random.Random, walk, seq: int) -> list:
    """One client's next message: a valid or broken command of every kind, or a skeleton frame."""
    frame = walk[rng.randrange(len(walk))]
    kind = rng.choice(["place", "place", "possess", "release", "subset", "fit", "skeleton", "skeleton", "junk"])
    if kind == "place":
        return {"type": "place", "scale": rng.choice([1.0, 0.5, 2.0, 1e308, -1, 0, 1e-9, 5e3]),
                "position": rng.choice([[0, 0, 0], [1.0, 0.0, -2.0], [0, 0, 1e6], [1e308, 0, 0], [0, 0]]),
                "yaw": rng.choice([0.0, 1.0, -3.0, 1e9, "x"]), **rng.choice([{}, {"mesh": 1}, {"mesh": 99}])}
    if kind == "possess":
        return {"type": "possess", "subset": rng.choice([None, "arms", ["left arm", "legs"], "wings", [], 7]),
                **rng.choice([{}, {"mesh": 1}, {"mesh": 2}, {"person": 2}, {"person": 0}])}
    if kind == "release":
        return {"type": "release", **rng.choice([{}, {"person": 1}, {"person": -3}])}
    if kind == "subset":
        return {"type": "subset", "subset": rng.choice([None, "spine", "upper body", "tail", {"a": 1}])}
    if kind == "fit":
        return {"type": "fit", **rng.choice([{}, {"mesh": 1}, {"mesh": 4}])}
    if kind == "skeleton":
        msg = json.loads(frame_message(seq, frame))
        if rng.random() < 0.3:  # a joint thrown across the world, or a frame missing its rows
            msg["positions"][rng.randrange(len(msg["positions"]))] = rng.choice([[0, 1e6, 0], [1e308, 0, 0], [1, 2]])
        return msg
    return rng.choice(['{"type": "place", "scale": 1e999}', "not json", '{"type": 3}', '{"type": "teleport"}',
                       "[]", '{"type": "possess", "mesh": true}'])


@pytest.fixture(scope="module")
def sample_studio():
    proc, url = start_server(sample_motion=True, nodes=64)
    yield url
    proc.terminate()
    proc.wait(10)


@pytest.mark.slow
def test_a_barrage_from_several_clients_keeps_the_scene_solving_for_a_viewer(sample_studio, walk):
    async def go():
        async with StudioClient(sample_studio) as viewer:
            # the sample performer possesses the mesh: transforms flow before anyone else arrives
            start = viewer.transform_count
            await viewer.wait(lambda c: c.transform_count >= start + 3, 120)
            clients = [StudioClient(sample_studio) for _ in range(3)]
            for c in clients:
                await c.__aenter__()
            try:
                # the message that once froze every viewer: refused, naming the field, and the sample plays on
                told = len(clients[0].messages)
                await clients[0].send({"type": "place", "scale": 1e308, "position": [0, 0, 0], "yaw": 0})
                await clients[0].wait(lambda c: any(m["type"] == "error" for m in c.messages[told:]))
                assert "scale must be within" in [m for m in clients[0].messages[told:] if m["type"] == "error"][0][
                    "message"]
                seen = viewer.transform_count
                await viewer.wait(lambda c: c.transform_count >= seen + 3, 120)

                rng = random.Random(0)
                for step in range(240):
                    c = clients[rng.randrange(len(clients))]
                    msg = barrage(rng, walk, step + 2)
                    await c.send(msg if isinstance(msg, str) else json.dumps(msg))
                    if step % 40 == 39:  # the scene answers as it goes: every client is still served
                        for k in clients:
                            await k.stats(120)

                # whoever possesses now, the scene still solves: one client stands, fits and possesses
                mover = clients[0]
                await mover.send({"type": "release"})
                await mover.wait(lambda c: c.me() and not c.me()["possessing"], 60)
                told = mover.me()["frames"]
                await mover.send(frame_message(10_000, walk[0]))
                await mover.wait(lambda c: c.me()["frames"] > told, 60)
                await mover.send({"type": "fit"})
                await mover.send({"type": "possess"})
                await mover.wait(lambda c: c.me()["possessing"], 120)
                seen = viewer.transform_count
                await mover.perform(walk, 10_001, lambda c: c.transform_count >= seen + 3, viewer)
                assert np.isfinite(viewer.matrices()).all()
                for m in viewer.state["meshes"]:
                    p = m["placement"]
                    check_placement(p["scale"], p["position"], p["yaw"])  # every placement stayed in bounds
            finally:
                for c in clients:
                    await c.__aexit__(None, None, None)

    asyncio.run(go())
