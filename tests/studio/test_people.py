"""Several people in one page's camera: each a user of its own, possessing the halves of one mesh through
the joint map wherever they stand; and the page's override of the mesh's up axis."""
import asyncio
import json
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
from studio.conftest import start_server
from studio.fixtures_horse import horse_obj
from studio.studio_ws import StudioClient, frame_message

from kinetre.skeleton.models import Skeleton
from kinetre.studio.protocol import ProtocolError, parse_person, person_client

ROOT = Path(__file__).resolve().parents[2]
HORSE_MAP = ROOT / "examples" / "maps" / "two-people-horse.json"


def shifted(skeleton: Skeleton, dx: float) -> Skeleton:
    return Skeleton(skeleton.model, skeleton.positions + [dx, 0.0, 0.0], skeleton.tracked)


def test_person_names_and_bad_person_fields():
    assert person_client("c3", None) == "c3" and person_client("c3", 2) == "c3p2"
    assert parse_person({"type": "fit"}) is None and parse_person({"person": 4}) == 4
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ProtocolError, match="'person' must be an integer"):
            parse_person({"person": bad})


@pytest.fixture(scope="module")
def horse_studio(tmp_path_factory):
    proc, url = start_server(str(horse_obj(tmp_path_factory.mktemp("horse") / "horse.obj")), nodes=64)
    yield url
    proc.terminate()
    proc.wait(10)


def test_two_people_in_one_camera_possess_the_two_halves(horse_studio, walk):
    studio = horse_studio
    httpx.post(studio + "/api/jointmap?name=two-people-horse.json", content=HORSE_MAP.read_bytes())

    async def go():
        async with StudioClient(studio) as page, StudioClient(studio) as viewer:
            for seq in range(1, 4):
                for person, dx in ((1, -1.0), (2, 1.0)):
                    msg = json.loads(frame_message(seq, shifted(walk[seq], dx)))
                    await page.send({**msg, "person": person})
            names = [person_client(page.client, p) for p in (1, 2)]
            await page.wait(lambda c: all(any(u["client"] == n and u["frames"] >= 3 for u in c.state["users"])
                                          for n in names))
            await page.send({"type": "fit", "person": 1})  # the horse stands on the first, 2 m from the second
            await page.wait(lambda c: c.state["meshes"][0]["placement"]["position"][0] < -0.5)
            for p in (1, 2):
                await page.send({"type": "possess", "person": p})
            await page.wait(lambda c: all(u["possessing"] for u in c.state["users"] if u["client"] in names)
                            and len([u for u in c.state["users"] if u["client"] in names]) == 2, 60)
            during = {u["client"]: u for u in page.state["users"]}
            await page._ws.close()
            await viewer.wait(lambda c: not any(u["client"].startswith(page.client) for u in c.state["users"]))
            return names, during, viewer.state

    names, users, after = asyncio.run(go())
    front, back = users[names[0]], users[names[1]]
    lower = ["HipCenter", "HipLeft", "KneeLeft", "AnkleLeft", "FootLeft", "HipRight", "KneeRight", "AnkleRight",
             "FootRight"]
    assert front["subset"] == lower and back["subset"] == lower  # each the lower body its map entry keeps
    # both stand in the horse, the map's offsets apart, wherever they are in the camera: both legs attach
    assert front["attached"] and back["attached"]
    assert not after["users"] or all(not u["possessing"] for u in after["users"])


def test_the_up_override_turns_the_mesh_and_back(studio):
    def turn(up):
        job = httpx.post(studio + f"/api/mesh/up?up={up}").json()["job"]
        deadline = time.monotonic() + 120
        while not (status := httpx.get(studio + f"/api/jobs/{job}").json())["done"]:
            assert time.monotonic() < deadline, status
            time.sleep(0.2)
        return httpx.get(studio + "/api/state").json()["meshes"][0]

    before = httpx.get(studio + "/api/state").json()["meshes"][0]
    assert before["up"] == "y" and before["name"] == "spot.obj"
    turned = turn("z")
    assert turned["up"] == "z" and turned["id"] == before["id"] + 1
    payload = httpx.get(studio + turned["url"]).json()
    import base64
    v = np.frombuffer(base64.b64decode(payload["positions"]), "<f4").reshape(-1, 3)
    assert np.ptp(v[:, 1]) == pytest.approx(1.6, rel=1e-3) and v[:, 1].min() == pytest.approx(0, abs=1e-4)
    assert turn("y")["up"] == "y"
    r = httpx.post(studio + "/api/mesh/up?up=w")
    assert r.status_code == 400 and "up must be one of y, z, x, -x, -y, -z" in r.json()["error"]
