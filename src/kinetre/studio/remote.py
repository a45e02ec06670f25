"""A scene in its own process (`kinetre scene`) and studios that only relay pages to it over NATS.

    page ─WS─ studio --remote-scene ─┐                        ┌─ kinetre scene (mesh, graph, rig, solver)
    page ─WS─ studio --remote-scene ─┼─ NATS room kinetre.R.* ┤
    capture/viewer NATS clients ─────┘                        └─ its solve worker process

The scene (a `LocalScene` served by `serve_scene`) subscribes to the room's skeleton subjects, solves, and
publishes transforms and its state (at least every `BEAT` s: its heartbeat). A gateway studio's scene host
(`GatewayScene`) forwards each page's commands (`command_subject`, every one delivered, in order), mirrors
the scene's state and newest transforms for pages that connect (`SceneMirror`), and fetches meshes and takes
from the scene by request/reply in chunks below NATS's message cap. When the heartbeat stops for
`LOST_AFTER` s the gateway tells its pages "scene lost"; the scene's next state clears it.
"""
from __future__ import annotations

import asyncio
import json
import logging
import time
from pathlib import Path

from ..errors import KinetreError
from ..wire.transforms import HEADER
from .channels import Frame, now_ms
from .host import LocalScene, answer_error, apply
from .jobs import MAX_UPLOAD, Job, Jobs
from .meshes import NODES, data_path, prepare_mesh
from .natsbus import NatsChannels, probe_nats
from .player import sample_player
from .protocol import ProtocolError, parse_message
from .recording import Takes
from .scene import MeshError, Scene
from .scene.solve_worker import SolveWorker, freeze_heap
from .subjects import (COMMANDS, FILES, JOBS, MESHES, STATE, TAKES, TRANSFORMS, UPLOAD,
                       command_subject, is_transforms, last_token, skeleton_subject)

log = logging.getLogger("kinetre.network")

BEAT = 0.5  # s between the scene's state messages
LOST_AFTER = 1.5  # s of silence before a gateway calls the scene lost
CHUNK = 512 * 1024  # bytes per request/reply message (NATS's default cap is 1 MB)
RECORDER = "studio"  # the command subject's client for "record": recording belongs to no page


def chunked(data: bytes, index: int) -> bytes:
    """Chunk `index` of `data`, after a line saying how many chunks there are."""
    count = max(1, -(-len(data) // CHUNK))
    if not 0 <= index < count:
        raise KinetreError(f"chunk {index} of {count}")
    return json.dumps({"chunks": count}).encode() + b"\n" + data[index * CHUNK:(index + 1) * CHUNK]


def answer(reply: bytes) -> bytes:
    """The body of a reply; an error reply (leading NUL, see NatsChannels.serve) raises KinetreError."""
    if reply[:1] == b"\x00":
        raise KinetreError(reply[1:].decode(errors="replace"))
    return reply


async def fetch(bus: NatsChannels, what: dict, timeout: float = 10.0) -> bytes:
    """A file from the scene (mesh payload or take file), reassembled from its chunks."""
    parts, count, index = [], 1, 0
    while index < count:
        reply = answer(await bus.request(FILES, json.dumps({**what, "chunk": index}).encode(), timeout))
        head, _, body = reply.partition(b"\n")
        count = json.loads(head)["chunks"]
        parts.append(body)
        index += 1
    return b"".join(parts)


# --- the gateway side ----------------------------------------------------------------------------------
class SceneMirror:
    """What a gateway knows of the remote scene: its last state and transforms, and whether it is alive."""

    def __init__(self, hub: NatsChannels):
        self.hub = hub
        self.latest: dict | None = None
        self.blocks: dict[int, bytes] = {}  # the newest transform block of each mesh, by mesh id
        self.heard = 0.0  # monotonic time of the last state
        self.lost = True  # until the scene is first heard

    @property
    def mesh_ids(self) -> list[int]:
        """The scene's meshes, in its order."""
        return [] if self.latest is None else [m["id"] for m in self.latest.get("meshes", ())]

    @property
    def mesh_id(self) -> int:
        return (self.mesh_ids or [0])[0]

    def state(self) -> dict:
        if self.latest is None:
            return {"type": "state", "meshes": [], "users": [], "recording": False, "solve_ms": None, "error": "",
                    "scene_lost": True}
        c = self.hub.counters
        return {**self.latest, "scene_lost": self.lost,
                "bus": {"gaps": c.gaps, "late": c.late, "offline": c.offline, "reconnects": c.reconnects}}

    def transforms_blocks(self) -> list[bytes]:
        return [self.blocks[i] for i in self.mesh_ids if i in self.blocks]

    async def run(self) -> None:
        """Follow the scene's state and transforms; announce "scene lost" to this gateway's pages."""
        sub = self.hub.subscribe(STATE, TRANSFORMS)
        watchdog = asyncio.get_running_loop().create_task(self._watch())
        try:
            while True:
                frame = await sub.next()
                if frame is None:
                    return
                if is_transforms(frame.subject):
                    if len(frame.data) >= HEADER.size:
                        self.blocks[HEADER.unpack_from(frame.data)[2]] = frame.data  # by the block's mesh id
                    continue
                try:
                    state = json.loads(frame.data)
                except ValueError:
                    continue
                if state.get("scene_lost"):
                    continue  # our own announcement, delivered locally
                self.latest, self.heard = state, time.monotonic()
                for gone in set(self.blocks) - set(self.mesh_ids):
                    del self.blocks[gone]  # a removed or replaced mesh
                # only the possessing users' frames are waited for (by the solve): the others' may be batched
                self.hub.batched = frozenset(skeleton_subject(u['client']) for u in state.get("users", ())
                                             if not u.get("possessing"))
                if self.lost:
                    self.lost = False
                    log.info("scene is back")
        finally:
            watchdog.cancel()
            sub.close()

    async def _watch(self) -> None:
        while True:
            await asyncio.sleep(0.25)
            if not self.lost and time.monotonic() - self.heard > LOST_AFTER:
                self.lost = True
                log.warning("scene lost: no state for %.1f s", LOST_AFTER)
                self.hub.deliver_local(Frame(STATE, 0, now_ms(), json.dumps(self.state()).encode()))


class GatewayScene:
    """The scene host of a studio whose scene runs elsewhere: pages' commands, uploads and takes go to it over
    NATS, and what pages see of it comes from the `SceneMirror`."""

    def __init__(self, hub: NatsChannels):
        self.hub = hub
        self.mirror = SceneMirror(hub)
        self.jobs = Jobs()
        self.takes = Takes()
        self.tasks: list[asyncio.Task] = []
        self._meshes: dict[int, bytes] = {}  # the mesh payloads fetched, by id

    @property
    def mesh_id(self) -> int:
        return self.mirror.mesh_id

    def state(self) -> dict:
        return self.mirror.state()

    def transforms_blocks(self) -> list[bytes]:
        return self.mirror.transforms_blocks()

    async def command(self, client: str, msg: dict, raw: bytes) -> None:
        self.hub.publish(Frame(command_subject(client), 0, now_ms(), raw))

    def forget(self, client: str) -> None:
        self.hub.publish(Frame(command_subject(client), 0, now_ms(), b'{"type": "bye"}'))

    def set_up(self, up: str, mesh_id: int | None = None) -> Job:
        raise KinetreError("this studio relays to a remote scene: its mesh is stood up on the scene's own studio")

    async def play_motion(self, name: str, data: bytes) -> dict:
        raise KinetreError("this studio relays to a remote scene: a motion file is played on the scene's own "
                           "studio, not through a gateway")

    def set_joint_map(self, joint_map) -> dict | None:
        raise KinetreError("this studio relays to a remote scene: a joint map is set on the scene's own "
                           "studio, not through a gateway")

    async def mesh_json(self, mesh_id: int) -> bytes | None:
        held = self.mirror.mesh_ids
        if mesh_id not in held:
            return None
        if mesh_id not in self._meshes:
            self._meshes[mesh_id] = await fetch(self.hub, {"mesh": mesh_id})
        for gone in set(self._meshes) - set(held):
            del self._meshes[gone]
        return self._meshes[mesh_id]

    async def remove_mesh(self, mesh_id: int) -> None:
        held = self.mirror.mesh_ids
        if mesh_id not in held:
            raise MeshError(f"no mesh {mesh_id} in the scene (its meshes: {', '.join(map(str, held))})", 404)
        answer(await self.hub.request(MESHES, json.dumps({"remove": mesh_id}).encode()))

    def start_recording(self) -> None:
        self.hub.publish(Frame(command_subject(RECORDER), 0, now_ms(), b'{"type": "record"}'))

    async def stop_recording(self) -> dict:
        result = json.loads(answer(await self.hub.request(TAKES, b"stop", timeout=120)))
        folder = self.takes.folder(result["take"])
        for href in result["files"].values():
            name = href.rsplit("/", 1)[-1]
            (folder / name).write_bytes(await fetch(self.hub, {"take": result["take"], "name": name}, 60))
        return result

    def start_job(self, name: str, data: bytes, scan_options: dict | None = None, add: bool = False) -> Job:
        """Send the upload to the scene in chunks; the local job follows the scene's job."""
        job = self.jobs.new(name)
        self.tasks.append(asyncio.get_running_loop().create_task(self._upload(job, data, scan_options or {}, add)))
        return job

    async def _upload(self, job: Job, data: bytes, scan_options: dict, add: bool) -> None:
        try:
            count = max(1, -(-len(data) // CHUNK))
            upload = f"{id(job)}-{job.id}"
            remote = None
            for index in range(count):
                job.stage, job.fraction = "sending to the scene", 0.05 * index / count
                head = {"upload": upload, "name": job.name, "part": index, "parts": count, "scan": scan_options,
                        "add": add}
                reply = answer(await self.hub.request(
                    UPLOAD, json.dumps(head).encode() + b"\n" + data[index * CHUNK:(index + 1) * CHUNK], 30))
                remote = json.loads(reply).get("job")
            while True:
                status = json.loads(answer(await self.hub.request(JOBS, json.dumps({"job": remote}).encode())))
                job.stage, job.fraction, job.error = status["stage"], status["fraction"], status["error"]
                job.mesh_id = status.get("mesh")
                if status["done"]:
                    job.done = True
                    return
                await asyncio.sleep(0.25)
        except KinetreError as exc:
            job.failed(f"{job.name}: {exc}")

    async def start(self) -> None:
        self.tasks.append(asyncio.get_running_loop().create_task(self.mirror.run()))

    async def close(self) -> None:
        for task in self.tasks:
            task.cancel()
        self.takes.close()


# --- the scene side ------------------------------------------------------------------------------------
async def serve_scene(mesh_path: str | None, url: str, room: str = "main", token: str | None = None,
                      nodes: int = NODES, sample_motion: bool = False, started=None, nkey: str | None = None,
                      clean: bool = True, contact: bool = False) -> None:
    """`kinetre scene`: run until cancelled. `started(host)` (the LocalScene) is called once it serves.
    `clean`, `contact`: how users' frames are cleaned before the solve (see `Scene`)."""
    await probe_nats(url, room, token, nkey)  # a refusal is reported before the mesh is loaded
    path = mesh_path or str(data_path("spot.obj"))
    mesh, graph = await asyncio.to_thread(prepare_mesh, path, nodes)
    # connected only once the scene exists: nobody may hear of it before it subscribes (see below)
    bus = NatsChannels(room)
    scene = Scene(bus, mesh, graph, Path(path).name, solver=SolveWorker(), new_solver=SolveWorker, clean=clean,
                  contact=contact)
    host = LocalScene(bus, scene, nodes=nodes, settle=0.1)  # the sample's frames make a round trip
    await bus.start(url, token, name="kinetre-scene", nkey=nkey)
    if sample_motion and mesh_path is None:
        host.player = sample_player(bus)
    uploads: dict[str, list[bytes]] = {}

    async def command(frame: Frame) -> None:
        client = last_token(frame.subject)
        try:
            msg = parse_message(frame.data)
        except ProtocolError as exc:
            answer_error(bus, client, exc)
            return
        if msg["type"] == "bye":
            host.forget(client)
        elif msg["type"] == "record":
            host.start_recording()
        else:
            await apply(host, bus, client, msg, frame.data)

    async def files(data: bytes) -> bytes:
        what = json.loads(data)
        if "mesh" in what:
            payload = await host.mesh_json(int(what["mesh"]))
            if payload is None:
                raise KinetreError(f"mesh {what['mesh']} is not loaded")
        else:
            file = host.takes.file(int(what["take"]), str(what["name"]))
            if file is None:
                raise KinetreError(f"no file {what['name']} in take {what['take']}")
            payload = file.read_bytes()
        return chunked(payload, int(what["chunk"]))

    async def takes(data: bytes) -> bytes:
        return json.dumps(await host.stop_recording()).encode()

    async def upload(data: bytes) -> bytes:
        head, _, body = data.partition(b"\n")
        head = json.loads(head)
        parts = uploads.setdefault(head["upload"], [])
        parts.append(body)
        if sum(map(len, parts)) > MAX_UPLOAD:
            del uploads[head["upload"]]
            raise KinetreError(f"over the {MAX_UPLOAD >> 20} MB limit")
        if head["part"] + 1 < head["parts"]:
            return b"{}"
        job = host.start_job(head["name"], b"".join(uploads.pop(head["upload"])), head.get("scan") or None,
                             add=bool(head.get("add")))
        return json.dumps({"job": job.id}).encode()

    async def jobs(data: bytes) -> bytes:
        job = host.jobs.get(json.loads(data)["job"])
        if job is None:
            raise KinetreError("no such job")
        return json.dumps(job.status()).encode()

    async def meshes(data: bytes) -> bytes:
        await host.remove_mesh(int(json.loads(data)["remove"]))
        return b"{}"

    async def beat() -> None:
        while True:
            await asyncio.sleep(BEAT)
            scene.publish_state()
            scene.publish_rest()  # idle meshes: gateways that joined late still get their poses

    await bus.listen(COMMANDS, command)
    for subject, handler in ((FILES, files), (TAKES, takes), (UPLOAD, upload), (JOBS, jobs), (MESHES, meshes)):
        await bus.serve(subject, handler)
    await host.start()
    heartbeat = asyncio.get_running_loop().create_task(beat())
    await asyncio.sleep(0.05)  # the scene's task subscribes to the skeletons when it first runs
    await bus.ready()  # …and the server has it before anyone hears that the scene is up
    scene.publish_state()
    freeze_heap()
    if started is not None:
        started(host)
    try:
        await asyncio.gather(heartbeat, *host.tasks)
    finally:
        heartbeat.cancel()
        await host.close()
        await bus.close()


def run_scene(mesh_path: str | None, url: str, room: str = "main", token: str | None = None, nodes: int = NODES,
              sample_motion: bool = False, nkey: str | None = None, clean: bool = True, contact: bool = False) -> None:
    """What `kinetre scene` runs: serve until interrupted. Raises KinetreError (NetworkError) on bad input."""
    def started(host: LocalScene) -> None:
        first = host.scene.meshes.first
        print(f"Kinetre scene: {first.name} ({first.graph.node_count} nodes) in room {room!r} "
              f"on {url} (Ctrl+C to stop)", flush=True)
    main = serve_scene(mesh_path, url, room, token, nodes, sample_motion, started, nkey, clean, contact)
    try:  # uvloop, as uvicorn runs the studio (uvicorn[standard] installs it): each message's hops are cheaper
        import uvloop
    except ImportError:
        asyncio.run(main)
    else:
        uvloop.run(main)
