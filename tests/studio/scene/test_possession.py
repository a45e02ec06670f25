"""Possession in the studio: with a joint map, two users possess one mesh, each with the joints its map entry
keeps (a bad map refused readably); a hand puppet, a page's user possessing a five-legged creature with their
right hand (the hands its skeleton frames carry), each leg following its finger, and possession by a hand not in
view refused in words."""
from __future__ import annotations

import asyncio
import base64
import json

import httpx
import numpy as np
import pytest
from studio.conftest import start_server
from studio.studio_ws import StudioClient, frame_message
from synthetic import REST, hand_creature, spread_hand, tpose

from kinetre.skeleton.models import KINECT20

WRIST = KINECT20.index("WristRight")


def test_two_users_possess_with_the_maps_joints(studio, walk):
    # both stand in the cow (the test sends the same pose twice; the map offsets neither): one drives with the
    # legs, one with the spine
    body = json.dumps({"sources": [{"keep": ["legs"], "rename": {"HipLeft": "FrontHipLeft"}},
                                   {"keep": ["spine"], "drop": ["Head"]}]})
    r = httpx.post(studio + "/api/jointmap?name=legs-and-spine.json", content=body)
    assert r.status_code == 200 and r.json()["joint_map"] == {"name": "legs-and-spine.json", "sources": 2}

    async def go():
        async with StudioClient(studio) as a, StudioClient(studio) as b:
            for c in (a, b):
                for i in range(2):
                    await c.send(frame_message(i + 1, walk[0]))
                await c.wait(lambda c: c.me() and c.me()["frames"] >= 1)
            await a.send({"type": "fit"})
            await a.send({"type": "possess"})
            await a.wait(lambda c: c.me() and c.me()["possessing"], 60)
            await b.send({"type": "possess"})
            await b.wait(lambda c: c.me() and c.me()["possessing"], 60)
            users = {u["client"]: u for u in b.state["users"]}
            return users[a.client], users[b.client], b.state["joint_map"]

    first, second, shown = asyncio.run(go())
    assert shown["sources"] == 2
    assert first["subset"] == ["HipLeft", "KneeLeft", "AnkleLeft", "FootLeft", "HipRight", "KneeRight",
                               "AnkleRight", "FootRight"]
    assert second["subset"] == ["HipCenter", "Spine", "ShoulderCenter"]
    assert first["attached"]  # the legs reach into the cow's legs
    assert httpx.request("DELETE", studio + "/api/jointmap").json()["joint_map"] is None


def test_a_bad_map_is_refused_readably(studio):
    r = httpx.post(studio + "/api/jointmap?name=m.json", content=json.dumps({"sources": [{"kep": []}]}))
    assert r.status_code == 400 and "m.json: sources[0]: unknown key(s) kep" in r.json()["error"]
    r = httpx.post(studio + "/api/jointmap?name=m.json", content=b"{not json")
    assert r.status_code == 400 and "not valid JSON" in r.json()["error"]



@pytest.fixture(scope="module")
def creature_studio(tmp_path_factory):
    surface, feet = hand_creature()
    path = tmp_path_factory.mktemp("creature") / "creature.obj"
    surface.export(path)
    proc, url = start_server(str(path), nodes=96)
    yield url, surface, feet
    proc.terminate()
    proc.wait(10)


def hand_frame(seq: int, curl, t: float) -> dict:
    """A skeleton message: a person in a T-pose, their right hand held like a spider at their right wrist."""
    body = tpose()
    hand = spread_hand(curl)
    hand += body.positions[WRIST] - hand[0]
    return {**json.loads(frame_message(seq, body, t)), "hands": [None, hand.tolist()]}


def mesh_arrays(url: str, mesh_id: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, graph nodes) of the studio's mesh, in its own frame."""
    payload = httpx.get(f"{url}/api/mesh/{mesh_id}", timeout=30).json()
    decode = lambda key: np.frombuffer(base64.b64decode(payload[key]), "<f4").reshape(-1, 3).astype(np.float64)  # noqa: E731
    return decode("positions"), decode("nodes")


def test_a_right_hand_possesses_the_creature_and_walks_its_legs(creature_studio):
    url, surface, feet = creature_studio

    async def go():
        async with StudioClient(url) as page:
            rest = np.full(5, REST)
            for seq in range(1, 4):
                await page.send(hand_frame(seq, rest, 1000.0 * seq))
            await page.wait(lambda c: (c.me() or {}).get("frames", 0) >= 3)
            await page.send({"type": "possess", "hand": "right"})
            await page.wait(lambda c: (c.me() or {}).get("possessing") and c.me()["hand"] == "right", 60)
            attached = len(page.me()["attached"])
            blocks = []
            for k, f in enumerate((None, 1, 4)):  # at rest, then the index and the little finger straighten
                curl = rest.copy()
                if f is not None:
                    curl[f] = np.radians(8.0)
                t = 4000.0 + 1000.0 * k
                await page.send(hand_frame(4 + k, curl, t))
                await page.wait(lambda c: c.transforms[2] == t, 60)
                blocks.append(page.transforms[4].astype(np.float64))
            return attached, page.state["meshes"][0]["id"], blocks

    attached, mesh_id, (bind, index, little) = asyncio.run(go())
    assert attached >= 10, f"{attached} of the hand's 21 joints attached"
    vertices, nodes = mesh_arrays(url, mesh_id)
    # the studio stood the creature up as it rests (+Y up), 1.6 m tall on the floor: its leg tips there
    lo, size = surface.vertices.min(axis=0), np.ptp(surface.vertices[:, 1])
    k = np.ptp(vertices[:, 1]) / size
    feet = k * (feet - lo) + vertices.min(axis=0)
    place = lambda m: np.einsum("nij,nj->ni", m[:, :3, :3], nodes) + m[:, :3, 3]  # noqa: E731
    held = np.linalg.norm(place(bind) - nodes, axis=1)
    assert held.max() < 0.02, f"at the bind pose the mesh moves {held.max():.3f} m"
    for f, m in ((1, index), (4, little)):
        moved = place(m) - place(bind)
        lift = np.linalg.norm(moved, axis=1)
        most = int(np.argmax(lift))
        assert lift[most] > 0.05, f"finger {f}: the mesh barely moves ({lift[most]:.3f} m)"
        # the node that moves most is on that finger's leg, and it lifts
        assert np.linalg.norm(feet - nodes[most], axis=1).argmin() == f
        assert moved[most, 1] > 0.5 * lift[most]


def test_possessing_by_a_hand_not_in_view_is_refused(creature_studio):
    url = creature_studio[0]

    async def go():
        async with StudioClient(url) as page:
            await page.send(frame_message(1, tpose(), 1000.0))
            await page.wait(lambda c: (c.me() or {}).get("frames", 0) >= 1)
            await page.send({"type": "possess", "hand": "left"})
            await page.wait(lambda c: any(m["type"] == "error" for m in c.messages))
            await page.send({"type": "possess", "hand": "both"})
            await page.wait(lambda c: sum(m["type"] == "error" for m in c.messages) >= 2)
            return [m["message"] for m in page.messages if m["type"] == "error"], page.me()

    errors, me = asyncio.run(go())
    assert "no left hand tracked" in errors[0] and "left" in errors[1] and not me["possessing"]
