"""The studio's joint map: two users possess one mesh, each with the joints its map entry keeps."""
import asyncio
import json

import httpx
from studio.studio_ws import StudioClient, frame_message


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
