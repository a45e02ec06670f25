"""Several meshes in one scene: each user possesses the mesh it names, each mesh is solved from its own
possessors only, on a subject of its own; releasing and removing a mesh let go; bad mesh ids are refused."""
import asyncio
import json
import time

import httpx
import numpy as np
import pytest
from studio.conftest import start_server
from studio.fixtures_horse import horse_obj
from studio.studio_ws import StudioClient, frame_message

import kinetre
from kinetre.skeleton.models import Skeleton
from kinetre.studio.channels import Frame, Hub
from kinetre.studio.meshes import data_path, prepare_mesh
from kinetre.studio.protocol import SkeletonFrame, person_client
from kinetre.studio.scene import MeshError, Scene
from kinetre.studio.subjects import TRANSFORMS, transforms_subject
from kinetre.wire.transforms import unpack_transforms


@pytest.fixture(scope="module")
def two_meshes(tmp_path_factory):
    spot = prepare_mesh(str(data_path("spot.obj")), 48)
    horse = prepare_mesh(str(horse_obj(tmp_path_factory.mktemp("horse") / "horse.obj")), 48)
    return spot, horse


def moved(skeleton: Skeleton, offset) -> Skeleton:
    return Skeleton(skeleton.model, skeleton.positions + np.asarray(offset, float), skeleton.tracked)


def shift(scene: Scene, mesh_id: int) -> np.ndarray:
    """Mean displacement (world metres) of the mesh's skinned vertices from rest, as placed."""
    m = scene.meshes[mesh_id]
    rest = m.mesh.vertices
    posed = kinetre.skin(m.mesh, m.graph, m.pose)
    return m.placement.scale * (posed - rest).mean(axis=0) @ m.placement.rotation.T


def test_each_user_drives_only_the_mesh_it_possesses(two_meshes, walk):
    (spot, spot_graph), (horse, horse_graph) = two_meshes
    hub = Hub()
    blocks = []
    hub.subscribe(TRANSFORMS).direct = lambda f: blocks.append((f.subject, f.data)) or True
    a0, b0 = walk[0], moved(walk[0], [2.5, 0, 0])  # two people 2.5 m apart

    async def go():
        # raw frames: people who jump 20 cm between frames 1 ms apart, which the live cleaning would smooth
        scene = Scene(hub, spot, spot_graph, "spot.obj", clean=False)
        second = scene.add_mesh(horse, horse_graph, "horse.obj")
        one = scene.meshes.first.id
        lo1, hi1 = scene.meshes[one].box()
        lo2, hi2 = scene.meshes[second].box()
        assert lo2[0] > hi1[0] + 0.2  # added beside the first, not inside it
        k = [0]

        def send(user, skeleton):
            k[0] += 1
            scene.receive(Frame(f"kinetre.skeleton.{user}", k[0], float(k[0]), b"",
                                SkeletonFrame(k[0], float(k[0]), skeleton)))
        send("a", a0)
        send("b", b0)
        scene.fit("a", one)
        scene.fit("b", second)
        assert scene.meshes[second].placement.position[0] > scene.meshes[one].placement.position[0] + 2
        await scene.possess("a", mesh_id=one)
        await scene.possess("b", mesh_id=second)
        state = scene.state()
        assert [m["possessors"] for m in state["meshes"]] == [["a"], ["b"]]
        assert {u["client"]: u["mesh"] for u in state["users"]} == {"a": one, "b": second}

        send("a", moved(a0, [0.2, 0, 0]))  # a steps 20 cm to the right
        send("b", moved(b0, [0, 0, -0.15]))  # b 15 cm back
        blocks.clear()
        await scene.solve_once(mesh_id=one)
        after_one = shift(scene, one), shift(scene, second), list(blocks)
        blocks.clear()
        await scene.solve_once(mesh_id=second)
        after_two = shift(scene, one), shift(scene, second), list(blocks)

        await scene.release("a")
        released = scene.state(), shift(scene, one)
        scene.fit("b", one)
        await scene.possess("b", mesh_id=one)  # b moves over to the first mesh: the second lets go
        switched = scene.state()
        scene.remove_mesh(second)
        removed = scene.state()
        return one, second, after_one, after_two, released, switched, removed

    one, second, after_one, after_two, released, switched, removed = asyncio.run(go())
    # solving the first mesh moves it with a, 20 cm along +x, and leaves the second at rest
    s1, s2, out = after_one
    assert s1[0] == pytest.approx(0.2, abs=0.04) and abs(s1[2]) < 0.04
    assert np.abs(s2).max() < 1e-6  # rest (float32 skinning)
    assert [(subject, unpack_transforms(b)[1]) for subject, b in out] == [(transforms_subject(one), one)]  # every mesh on a subject of its own
    # then the second mesh follows b, 15 cm along -z; the first keeps its pose
    t1, t2, out = after_two
    np.testing.assert_allclose(t1, s1, atol=1e-6)
    assert t2[2] == pytest.approx(-0.15, abs=0.03) and abs(t2[0]) < 0.03
    assert [(subject, unpack_transforms(b)[1]) for subject, b in out] == [(transforms_subject(second), second)]
    state, rest = released
    assert [m["possessors"] for m in state["meshes"]] == [[], ["b"]] and np.abs(rest).max() < 1e-6
    assert [m["possessors"] for m in switched["meshes"]] == [["b"], []]
    assert [m["id"] for m in removed["meshes"]] == [one]
    assert removed["meshes"][0]["possessors"] == ["b"]


def test_removing_a_mesh_releases_its_possessors_and_bad_ids_are_refused(two_meshes, walk):
    (spot, spot_graph), (horse, horse_graph) = two_meshes

    async def go():
        scene = Scene(Hub(), spot, spot_graph, "spot.obj")
        second = scene.add_mesh(horse, horse_graph, "horse.obj")
        scene.receive(Frame("kinetre.skeleton.b", 1, 1.0, b"", SkeletonFrame(1, 1.0, walk[0])))
        scene.fit("b", second)
        await scene.possess("b", mesh_id=second)
        with pytest.raises(MeshError, match=r"no mesh 7 in the scene \(its meshes: 1, 2\)") as unknown:
            await scene.possess("b", mesh_id=7)
        assert unknown.value.status == 404
        assert scene.users["b"].mesh == second  # a refused possession keeps the mesh it had
        scene.start_recording()
        with pytest.raises(MeshError, match="being recorded"):
            scene.remove_mesh(second)
        scene.stop_recordings()
        scene.remove_mesh(second)
        user = scene.state()["users"][0]
        with pytest.raises(MeshError, match="only mesh"):
            scene.remove_mesh(scene.meshes.first.id)
        with pytest.raises(MeshError, match="no mesh 2"):
            scene.fit("b", second)
        return user, scene.users["b"]

    user, b = asyncio.run(go())
    assert user["possessing"] is False and user["mesh"] is None and b.bind is None


def wait_job(studio: str, job: int, headers: dict | None = None) -> dict:
    """The upload job's status once done."""
    deadline = time.monotonic() + 180
    while not (status := httpx.get(f"{studio}/api/jobs/{job}", headers=headers).json())["done"]:
        assert time.monotonic() < deadline, status
        time.sleep(0.3)
    return status


@pytest.mark.slow  # a studio server process
def test_the_studio_adds_a_mesh_each_person_possesses_one_and_removing_it_lets_go(tmp_path, walk):
    proc, studio = start_server(None, nodes=32)
    try:
        horse = horse_obj(tmp_path / "horse.obj").read_bytes()
        r = httpx.post(f"{studio}/api/mesh?name=horse.obj&add=2", content=horse)
        assert r.status_code == 400 and "add must be 0" in r.json()["error"]
        status = wait_job(studio, httpx.post(f"{studio}/api/mesh?name=horse.obj&add=1", content=horse).json()["job"])
        state = httpx.get(f"{studio}/api/state").json()
        one, two = [m["id"] for m in state["meshes"]]
        assert status["mesh"] == two and state["meshes"][0]["id"] == one and state["meshes"][1]["name"] == "horse.obj"
        assert httpx.get(f"{studio}/api/mesh/{two}").json()["id"] == two
        for method, path, code, text in (("GET", "/api/mesh/9", 404, "mesh 9 is not loaded"),
                                          ("DELETE", "/api/mesh/9", 404, "no mesh 9 in the scene (its meshes: 1, 2)"),
                                          ("POST", "/api/mesh/up?up=z&mesh=x", 400, "mesh must be a mesh id"),
                                          ("POST", "/api/mesh/up?up=z&mesh=9", 404, "no mesh 9")):
            r = httpx.request(method, studio + path)
            assert r.status_code == code and text in r.json()["error"], (path, r.text)

        async def go():
            async with StudioClient(studio) as page:
                start = time.time() * 1000

                async def frames(k):  # stamped as a 30 fps camera would (the live cleaning filters by time)
                    for person, dx in ((1, -1.2), (2, 1.2)):
                        msg = json.loads(frame_message(k, moved(walk[k], [dx, 0, 0]), t=start + k * 1000 / 30))
                        await page.send({**msg, "person": person})
                for k in range(1, 4):
                    await frames(k)
                names = [person_client(page.client, p) for p in (1, 2)]
                await page.wait(lambda c: sum(u["client"] in names and u["frames"] >= 3 for u in c.state["users"]) == 2)
                await page.send({"type": "possess", "person": 1, "mesh": 9})
                await page.wait(lambda c: any(m["type"] == "error" for m in c.messages))
                error = [m for m in page.messages if m["type"] == "error"][-1]["message"]
                for person, mesh in ((1, one), (2, two)):
                    await page.send({"type": "fit", "person": person, "mesh": mesh})
                    await page.send({"type": "possess", "person": person, "mesh": mesh})
                await page.wait(lambda c: [m["possessors"] for m in c.state["meshes"]] == [[names[0]], [names[1]]], 60)
                httpx.post(f"{studio}/api/record/start")
                seqs = {i: page.mesh_transforms[i][0] for i in (one, two)}
                for k in range(4, 40, 3):
                    await frames(k)
                    await asyncio.sleep(0.05)
                await page.wait(lambda c: all(c.mesh_transforms[i][0] > seqs[i] + 3 for i in (one, two)), 60)
                moved_by = {i: float(np.abs(page.mesh_transforms[i][4][:, :3, 3]).max()) for i in (one, two)}
                take = httpx.post(f"{studio}/api/record/stop", timeout=120).json()
                r = httpx.delete(f"{studio}/api/mesh/{two}")
                await page.wait(lambda c: len(c.state["meshes"]) == 1)
                users = {u["client"]: u for u in page.state["users"]}
                return error, moved_by, take, r, users, names

        error, moved_by, take, removed, users, names = asyncio.run(go())
        assert error == f"no mesh 9 in the scene (its meshes: {one}, {two})"
        assert min(moved_by.values()) > 0.01, moved_by  # each mesh's nodes moved with its own person
        assert {m["id"] for m in take["meshes"]} == {one, two} and {f"glb-{one}", f"glb-{two}"} <= set(take["files"])
        for m in take["meshes"]:  # each mesh's files the same way, by its id
            assert m["files"]["glb"] == take["files"][f"glb-{m['id']}"]
            assert m["files"]["glb"].endswith(f"/take-mesh{m['id']}.glb")
            assert httpx.get(studio + m["files"]["glb"]).content[:4] == b"glTF"
        assert removed.status_code == 200
        assert users[names[0]]["possessing"] and users[names[0]]["mesh"] == one
        assert not users[names[1]]["possessing"] and users[names[1]]["mesh"] is None
        r = httpx.delete(f"{studio}/api/mesh/{one}")
        assert r.status_code == 400 and "only mesh" in r.json()["error"]
    finally:
        proc.terminate()
        proc.wait(10)
