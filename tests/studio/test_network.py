"""Networked scenes over a real nats-server: a scene process and a studio that talk only over
NATS, room tokens, room isolation, a NATS server killed and restarted, a scene killed and restarted
(pages are told "scene lost"), and a take that survives its recorder being killed.

nats-server must be installed (the Makefile's APT_PACKAGES): without it these tests fail, never skip.
"""
import asyncio
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
from studio.conftest import start_server
from studio.fixtures_horse import horse_obj
from studio.nats_server import ROOMS, NatsServer
from studio.studio_ws import StudioClient, frame_message
from studio.scene.test_meshes import moved, wait_job

from kinetre.cli import main
from kinetre.studio.channels import Frame, Hub
from kinetre.studio.meshes import data_path, prepare_mesh
from kinetre.studio.natsbus import NatsChannels, NetworkError
from kinetre.studio.protocol import SkeletonFrame, person_client
from kinetre.studio.scene import Scene
from kinetre.studio.scene.takes import read_take_log
from kinetre.wire.transforms import unpack_transforms

NODES = 64
A, B = ROOMS["a"], ROOMS["b"]


def start_scene(url: str, tmp: Path, room: str = "a", token: str = A, timeout: float = 120) -> subprocess.Popen:
    """`kinetre scene` in its own process; returns once its first state is on the bus."""
    env = dict(os.environ, PYTHONUNBUFFERED="1", TMPDIR=str(tmp))
    path = tmp / "scene.log"
    before = path.read_text().count("Kinetre scene") if path.exists() else 0  # earlier scenes logged here too
    log = open(path, "ab")
    proc = subprocess.Popen([sys.executable, "-m", "kinetre.cli", "scene", "--nats", url, "--room", room,
                             "--token", token, "--nodes", str(NODES)], env=env, stdout=log, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + timeout
    while path.read_text().count("Kinetre scene") <= before:
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise RuntimeError("scene did not start: " + (tmp / "scene.log").read_text()[-2000:])
        time.sleep(0.2)
    return proc


def stop(proc) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


@pytest.fixture(scope="module")
def network():
    """A nats-server with rooms a and b, a scene process and a gateway studio for room a."""
    tmp = Path(tempfile.mkdtemp(prefix="kinetre-net-test-"))
    with NatsServer() as nats:
        scene = start_scene(nats.url, tmp)
        studio, url = start_server(nats=nats.url, room="a", token=A, remote_scene=True)
        box = {"nats": nats, "scene": scene, "studio": studio, "url": url, "tmp": tmp}
        try:
            yield box
        finally:
            stop(box["studio"])
            stop(box["scene"])
            shutil.rmtree(tmp, ignore_errors=True)


def wait_for(client, t_source: float, timeout: float = 30.0):
    """The client's first transform block solved from the frame stamped `t_source`."""
    async def go():
        await client.wait(lambda c: any(t == t_source for t, _ in c.arrivals), timeout)
    return go()


async def possess(c: StudioClient, skeleton, subset=None) -> float:
    """Send one frame, fit, possess; returns the frame's timestamp once the solve of it arrived."""
    t0 = time.time() * 1000
    await c.send(frame_message(1, skeleton, t=t0))
    await c.wait(lambda c: c.me() is not None and c.me()["frames"] >= 1, 30)
    await c.send({"type": "fit"})
    await c.send({"type": "possess", "subset": subset})
    await c.wait(lambda c: (c.me() or {}).get("possessing") or any(m["type"] == "error" for m in c.messages), 60)
    assert c.me()["possessing"], [m for m in c.messages if m["type"] == "error"]
    await wait_for(c, t0)
    return t0


def test_scene_process_solves_what_a_local_scene_solves(network, walk):
    """Studio and scene in two processes, talking only over NATS: the pose equals an in-process solve.

    The scene's live solve of a frame may yield once the frame is late (a busy machine) and publish the pose
    it reached; with no newer frame it then solves the same frame on from there, so its last pose for the
    frame is the in-process solve's (which runs to the end at once)."""
    url = network["url"]

    async def local(t0, t1):  # the same frames, at the same times (the live cleaning filters by them)
        mesh_, graph = prepare_mesh(str(data_path("spot.obj")), NODES)
        hub = Hub()
        scene = Scene(hub, mesh_, graph, "spot.obj")
        scene.receive(Frame("kinetre.skeleton.u", 1, t0, b"", SkeletonFrame(1, t0, walk[0])))
        scene.fit("u")
        await scene.possess("u")
        await scene.solve_once()
        scene.receive(Frame("kinetre.skeleton.u", 2, t1, b"", SkeletonFrame(2, t1, walk[10])))
        await scene.solve_once()
        return scene.meshes.first.pose.node_matrices(graph.nodes), graph

    async def remote():
        async with StudioClient(url, A) as c:
            t0 = await possess(c, walk[0])
            t1 = time.time() * 1000
            await c.send(frame_message(2, walk[10], t=t1))
            expected, graph = await local(t0, t1)
            tol = 2e-4 * max(1.0, np.abs(expected - np.eye(4)).max())

            def newest(c):  # the last pose published for the frame
                return next((b for t, b in reversed(c.blocks) if t == t1), None)

            def solved(c):
                block = newest(c)
                return block is not None and np.abs(unpack_transforms(block)[4] - expected).max() <= tol
            try:
                await c.wait(solved, 60)
            except TimeoutError:
                pass  # the assertion below says by how much
            nodes = c.state["meshes"][0]["nodes"]
            async with httpx.AsyncClient(base_url=url, params={"token": A}) as http:
                mesh = (await http.get(c.state["meshes"][0]["url"])).json()  # fetched from the scene over NATS
            return newest(c), nodes, mesh, expected, graph, tol

    block, nodes, mesh, expected, graph, tol = asyncio.run(remote())
    assert block is not None, "no pose was published for the frame"
    _, _, _, _, matrices = unpack_transforms(block)
    assert nodes == graph.node_count == mesh["nodeCount"] == matrices.shape[0]
    moved = np.abs(expected - np.eye(4)).max()
    assert moved > 0.01  # the walk frame really deforms the mesh
    np.testing.assert_allclose(matrices, expected, atol=tol)


def test_studio_with_its_own_scene_on_nats(network, walk):
    """`kinetre studio --nats` without --remote-scene: the scene runs in the studio and its channels are room b's
    NATS subjects, so a capture client on another machine drives it straight over the bus and every solved
    block is on the bus too, byte for byte what the studio's own pages get."""
    nats_url = network["nats"].url
    studio, url = start_server(nodes=NODES, nats=nats_url, room="b", token=B)

    async def go():
        bus = await NatsChannels.connect(nats_url, "b", B)
        seen = bus.subscribe("kinetre.transforms.*")
        await bus.ready()
        async with StudioClient(url, B) as page:
            await possess(page, walk[0])  # page → studio → NATS → the studio's scene → NATS → studio → page
            # a capture client elsewhere, publishing on the bus only: the scene counts its frames
            bus.publish(Frame("kinetre.skeleton.elsewhere", 1, time.time() * 1000, frame_message(1, walk[3]).encode()))
            await page.wait(lambda c: any(u["client"] == "elsewhere" and u["frames"] == 1 for u in c.state["users"]),
                            30)
            t1 = time.time() * 1000
            await page.send(frame_message(2, walk[10], t=t1))
            await wait_for(page, t1)
            block = next(b for t, b in page.blocks if t == t1)
            while (frame := await seen.next(10)) is not None:
                if unpack_transforms(frame.data)[2] == t1:
                    await bus.close()
                    return block, frame.data, page.state["meshes"][0]["nodes"]
        await bus.close()
        return block, None, page.state["meshes"][0]["nodes"]

    try:
        block, on_bus, nodes = asyncio.run(go())
    finally:
        stop(studio)
    assert on_bus == block
    assert unpack_transforms(block)[4].shape[0] == nodes > 0


def test_room_tokens_are_required(network):
    url = network["url"]
    assert httpx.get(url + "/api/state").status_code == 401
    refused = httpx.get(url + "/api/state", params={"token": B})
    assert refused.status_code == 401 and "wrong token" in refused.json()["error"]
    page = httpx.get(url + "/api/state", params={"token": A})
    assert page.status_code == 200 and page.cookies.get("kinetre_a") == A  # the page's later requests
    assert httpx.get(url + "/api/state", cookies={"kinetre_a": A}).status_code == 200

    async def ws_refused():
        from websockets.asyncio.client import connect
        async with connect(url.replace("http", "ws") + "/ws") as ws:
            message = json.loads(await ws.recv())
            with pytest.raises(Exception):
                await ws.recv()
            return message, ws.close_code

    message, code = asyncio.run(ws_refused())
    assert message["type"] == "error" and "needs its token" in message["message"] and code == 4401

    async def bus_refused():
        for token in (None, "guess", B):
            with pytest.raises(NetworkError, match="refused"):
                await NatsChannels.connect(network["nats"].url, "a", token)
    asyncio.run(bus_refused())
    # the command line: one line, exit 2, before anything heavy loads
    assert main(["scene", "--nats", network["nats"].url, "--room", "a", "--token", "nope"]) == 2
    assert main(["studio", "--host", "0.0.0.0", "--no-browser"]) == 2


def test_rooms_are_isolated(network, walk):
    """Room a's clients neither read nor write room b, through the studio or straight on the bus."""
    nats_url, url = network["nats"].url, network["url"]

    async def go():
        a = await NatsChannels.connect(nats_url, "a", A)
        b = await NatsChannels.connect(nats_url, "b", B)
        seen_a = a.subscribe("kinetre.skeleton.*")
        seen_b = b.subscribe("kinetre.skeleton.*", "kinetre.transforms.*", "kinetre.state")
        await a.ready()
        await b.ready()
        async with StudioClient(url, A) as c:  # a page of room a, through the gateway
            await c.send(frame_message(1, walk[0]))
            got_a = await seen_a.next(10)
        # straight on the bus with room a's credentials, aiming at room b's subjects
        spy = await NatsChannels.connect(nats_url, "a", A)
        spy.prefix = "kinetre.b."
        spy_sub = spy.subscribe("kinetre.skeleton.*")
        with pytest.raises(NetworkError, match="ermissions violation"):
            await spy.ready()
        spy.publish(Frame("kinetre.skeleton.intruder", 1, 1.0, b"{}"))
        await asyncio.sleep(0.5)
        got_b = seen_b.poll()
        for bus in (a, b, spy):
            await bus.close()
        return got_a, got_b, spy_sub.poll()

    got_a, got_b, spied = asyncio.run(go())
    assert got_a is not None and json.loads(got_a.data)["type"] == "skeleton"
    assert got_b is None and spied is None


def test_nats_restart_and_scene_loss(network, walk):
    """kill -9 of nats-server: frames flow again once it is back; kill -9 of the scene: the page
    is told "scene lost" and recovers when a new scene starts; the take being recorded keeps every
    frame a viewer saw."""
    url, nats, tmp = network["url"], network["nats"], network["tmp"]

    async def stream(c, seconds, first_seq):
        """Frames at 30 Hz for `seconds`; returns the timestamps sent."""
        sent = []
        for i in range(int(seconds * 30)):
            t = time.time() * 1000
            await c.send(frame_message(first_seq + i, walk[(first_seq + i) % len(walk)], t=t))
            sent.append(t)
            await asyncio.sleep(1 / 30)
        return sent

    async def go():
        async with StudioClient(url, A) as c:
            await possess(c, walk[0])
            # 1. the NATS server dies and comes back
            await stream(c, 0.5, 10)
            nats.kill()
            await stream(c, 0.5, 100)
            nats.start()
            sent = set(await stream(c, 3.0, 200))
            after = [arrived for t, arrived in c.arrivals if t in sent]
            assert after, ("no transforms after the NATS server came back: "
                           + json.dumps([c.arrivals[-3:], (c.state or {}).get("bus"), (c.state or {}).get("users")])
                           + (tmp / "scene.log").read_text()[-1500:])
            # 2. a take is recording when the scene process dies
            async with httpx.AsyncClient(base_url=url, params={"token": A}) as http:
                assert (await http.post("/api/record/start")).status_code == 200
            await c.wait(lambda c: c.state.get("recording"), 30)
            mark = len(c.blocks)
            sent = set(await stream(c, 1.0, 400))
            network["scene"].kill()
            network["scene"].wait(10)
            await c.wait(lambda c: c.state.get("scene_lost"), 30)
            recorded_seen = {unpack_transforms(b)[0] for t, b in c.blocks[mark:] if t in sent}
            # 3. a new scene comes back: the page hears it, possesses again, frames flow
            network["scene"] = start_scene(nats.url, tmp)
            try:
                await c.wait(lambda c: not c.state.get("scene_lost"), 30)
            except TimeoutError:
                states = [m for m in c.messages if m["type"] == "state"][-6:]
                async with httpx.AsyncClient(base_url=url, params={"token": A}) as http:
                    mirror = (await http.get("/api/state")).json()
                raise AssertionError(json.dumps([(s.get("scene_lost"), s.get("bus"), s["users"]) for s in states])
                                     + json.dumps([mirror.get("scene_lost"), mirror.get("bus"), mirror.get("users")])
                                     + (tmp / "scene.log").read_text()[-1500:]) from None
            await possess(c, walk[0])
            return recorded_seen

    recorded_seen = asyncio.run(go())
    logs = list(tmp.glob("kinetre-recording-*/take-mesh*.log.jsonl"))
    assert len(logs) == 1
    on_disk = {frame[0] for frame in read_take_log(logs[0])}
    assert len(recorded_seen) >= 5 and recorded_seen <= on_disk  # every frame a viewer saw was recorded


def test_page_says_scene_lost_and_recovers(network):
    """The real page (Chromium) behind the gateway: "scene lost" in its status when the scene process is
    killed, "the scene is back" when a new one starts."""
    root = Path(__file__).resolve().parents[2]
    assert (root / "src" / "kinetre" / "studio" / "static" / "index.html").is_file(), "run `make web` first"
    config = {"url": f"{network['url']}/?token={A}&noshadows", "artifacts": str(root / "tests" / "e2e" / "artifacts")}
    driver = subprocess.Popen(["node", str(root / "tests" / "e2e" / "driver_network.mjs"), json.dumps(config)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=root)
    try:
        lines = []
        for line in driver.stdout:  # the driver paces the kills: READY → kill, LOST → restart
            lines.append(line.strip())
            if line.strip() == "READY":
                network["scene"].kill()
                network["scene"].wait(10)
            elif line.strip() == "LOST":
                network["scene"] = start_scene(network["nats"].url, network["tmp"])
        driver.wait(120)
    finally:
        if driver.poll() is None:
            driver.kill()
    assert lines and lines[-1].startswith("{"), driver.stderr.read()[-2000:]
    result = json.loads(lines[-1])
    assert result["ok"], result
    assert "scene lost" not in result["before"]["status"] and "connected as" in result["before"]["status"]
    assert "scene lost" in result["lost"]["status"] and "scene lost" in result["lost"]["message"]
    assert "scene lost" not in result["after"]["status"] and result["after"]["meshId"] is not None


def test_gateway_answers_bad_messages_and_forwards_good_frames(network, walk):
    """The gateway parses each page message once: malformed ones are answered with the reason (nothing goes
    to the scene), a good skeleton frame reaches the scene, which counts it for that page."""
    async def go():
        async with StudioClient(network["url"], A) as c:
            await c.send("not json")
            await c.send({"type": "skeleton", "seq": 1, "t": 1.0})
            await c.send({"type": "dance"})
            await c.wait(lambda c: sum(m["type"] == "error" for m in c.messages) >= 3, 30)
            errors = [m["message"] for m in c.messages if m["type"] == "error"]
            await c.send(frame_message(7, walk[3], t=time.time() * 1000))
            await c.wait(lambda c: (c.me() or {}).get("frames") == 1, 30)
            await c.send({"type": "stats"})
            await c.wait(lambda c: any(m["type"] == "stats" for m in c.messages), 30)
            return errors, next(m for m in c.messages if m["type"] == "stats")
    errors, stats = asyncio.run(go())
    assert "not JSON" in errors[0] and "positions" in errors[1] and "unknown message type 'dance'" in errors[2]
    assert stats["malformed"] == 3 and stats["received"] == 1 and stats["last_seq"] == 7


def test_a_remote_scene_of_two_meshes_is_mirrored_per_mesh(network, walk, tmp_path):
    """Through a gateway: a mesh added to the remote scene, each of two people possessing one, both meshes'
    transforms arriving (each on its own subject), and removing the added mesh releasing its possessor."""
    url = network["url"]
    auth = {"Authorization": f"Bearer {A}"}
    job = httpx.post(f"{url}/api/mesh?name=horse.obj&add=1", content=horse_obj(tmp_path / "h.obj").read_bytes(),
                     headers=auth).json()["job"]
    added = wait_job(url, job, auth)["mesh"]
    state = httpx.get(f"{url}/api/state", headers=auth).json()
    one = state["meshes"][0]["id"]
    assert [m["id"] for m in state["meshes"]] == [one, added]
    assert httpx.get(f"{url}/api/mesh/{added}", headers=auth).json()["name"] == "horse.obj"  # fetched over NATS

    async def go():
        async with StudioClient(url, A) as c:
            names = [person_client(c.client, p) for p in (1, 2)]
            for k in range(1, 4):
                for person, dx in ((1, -1.2), (2, 1.2)):
                    await c.send({**json.loads(frame_message(k, moved(walk[k], [dx, 0, 0]))), "person": person})
            await c.wait(lambda c: sum(u["client"] in names for u in c.state["users"]) == 2, 30)
            for person, mesh in ((1, one), (2, added)):
                await c.send({"type": "fit", "person": person, "mesh": mesh})
                await c.send({"type": "possess", "person": person, "mesh": mesh})
            await c.wait(lambda c: [m["possessors"] for m in c.state["meshes"]] == [[names[0]], [names[1]]], 60)
            seqs = {i: c.mesh_transforms.get(i, (0,))[0] for i in (one, added)}
            for k in range(4, 30, 3):
                for person, dx in ((1, -1.2), (2, 1.2)):
                    await c.send({**json.loads(frame_message(k, moved(walk[k], [dx, 0, 0]))), "person": person})
                await asyncio.sleep(0.05)
            await c.wait(lambda c: all(c.mesh_transforms.get(i, (0,))[0] > seqs[i] + 2 for i in (one, added)), 60)
            unknown = httpx.delete(f"{url}/api/mesh/99", headers=auth)
            removed = httpx.delete(f"{url}/api/mesh/{added}", headers=auth)
            await c.wait(lambda c: len(c.state["meshes"]) == 1, 30)
            users = {u["client"]: u for u in c.state["users"]}
            return unknown, removed, users, names

    unknown, removed, users, names = asyncio.run(go())
    assert unknown.status_code == 404 and "no mesh 99" in unknown.json()["error"]
    assert removed.status_code == 200
    assert users[names[0]]["mesh"] == one and not users[names[1]]["possessing"]
