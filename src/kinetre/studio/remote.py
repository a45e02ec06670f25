"""A scene in its own process (`kinetre scene`) and studios that only relay pages to it over NATS (issue 12).

    page ─WS─ studio --remote-scene ─┐                        ┌─ kinetre scene (mesh, graph, rig, solver)
    page ─WS─ studio --remote-scene ─┼─ NATS room kinetre.R.* ┤
    capture/viewer NATS clients ─────┘                        └─ its solve worker process

The scene subscribes to the room's skeleton subjects, solves, and publishes transforms and its state
(at least every `BEAT` s: its heartbeat). A gateway studio forwards each page's skeleton frames and
commands (`kinetre.command.<client>`, every one delivered, in order), mirrors the scene's state and
newest transforms for pages that connect, and fetches meshes and takes from the scene by
request/reply in chunks below NATS's message cap. When the heartbeat stops for `LOST_AFTER` s the
gateway tells its pages "scene lost"; the scene's next state clears it.
"""
from __future__ import annotations

import asyncio
import json
import logging
import time
from pathlib import Path

from ..errors import KinetreError
from .app import MAX_UPLOAD, ClientStats, Job, Studio, data_path, prepare_mesh, probe_nats, sample_player
from .channels import Frame
from .natsbus import NatsChannels
from .placement import Placement
from .protocol import ProtocolError, parse_message
from .scene import STATE, TRANSFORMS, Scene, now_ms, skeleton_subject
from .solve_worker import SolveWorker, freeze_heap

log = logging.getLogger("kinetre.network")

BEAT = 0.5  # s between the scene's state messages
LOST_AFTER = 1.5  # s of silence before a gateway calls the scene lost
CHUNK = 512 * 1024  # bytes per request/reply message (NATS's default cap is 1 MB)
FORWARD = ("possess", "release", "subset", "place", "fit", "player")  # commands the scene applies
FILES, UPLOAD, JOBS, TAKES = "kinetre.files", "kinetre.upload", "kinetre.jobs", "kinetre.takes"


def _command(client: str) -> str:
    return f"kinetre.command.{client}"


def _chunked(data: bytes, index: int) -> bytes:
    count = max(1, -(-len(data) // CHUNK))
    if not 0 <= index < count:
        raise KinetreError(f"chunk {index} of {count}")
    return json.dumps({"chunks": count}).encode() + b"\n" + data[index * CHUNK:(index + 1) * CHUNK]


def _answer(reply: bytes) -> bytes:
    """The body of a reply; an error reply (leading NUL, see NatsChannels.serve) raises KinetreError."""
    if reply[:1] == b"\x00":
        raise KinetreError(reply[1:].decode(errors="replace"))
    return reply


async def fetch(bus: NatsChannels, what: dict, timeout: float = 10.0) -> bytes:
    """A file from the scene (mesh payload or take file), reassembled from its chunks."""
    parts, count, index = [], 1, 0
    while index < count:
        reply = _answer(await bus.request(FILES, json.dumps({**what, "chunk": index}).encode(), timeout))
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
        self.block: bytes | None = None
        self.heard = 0.0  # monotonic time of the last state
        self.lost = True  # until the scene is first heard
        self.users: dict = {}  # Studio.start_sample looks here; the sample motion runs in the scene

    @property
    def mesh_id(self) -> int:
        return self.latest["mesh"]["id"] if self.latest else 0

    def state(self) -> dict:
        if self.latest is None:
            return {"type": "state", "mesh": None, "placement": Placement().as_dict(), "users": [],
                    "recording": False, "solve_ms": None, "error": "", "scene_lost": True}
        c = self.hub.counters
        return {**self.latest, "scene_lost": self.lost,
                "bus": {"gaps": c.gaps, "late": c.late, "offline": c.offline, "reconnects": c.reconnects}}

    def transforms_block(self) -> bytes | None:
        return self.block

    def forget(self, client: str) -> None:
        self.hub.publish(Frame(_command(client), 0, now_ms(), b'{"type": "bye"}'))

    def start_recording(self) -> None:
        self.hub.publish(Frame(_command("studio"), 0, now_ms(), b'{"type": "record"}'))

    async def run(self) -> None:
        """Follow the scene's state and transforms; announce "scene lost" to this gateway's pages."""
        sub = self.hub.subscribe(STATE, TRANSFORMS)
        watchdog = asyncio.get_running_loop().create_task(self._watch())
        try:
            while True:
                frame = await sub.next()
                if frame is None:
                    return
                if frame.subject == TRANSFORMS:
                    self.block = frame.data
                    continue
                try:
                    state = json.loads(frame.data)
                except ValueError:
                    continue
                if state.get("scene_lost"):
                    continue  # our own announcement, delivered locally
                self.latest, self.heard = state, time.monotonic()
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


class GatewayStudio(Studio):
    """A studio whose scene runs elsewhere: pages' commands, uploads and takes go to it over NATS."""

    async def handle(self, client: str, text: str | bytes) -> None:
        try:
            msg = parse_message(text)
        except ProtocolError:
            msg = None  # the base class answers the error
        if msg is not None and msg["type"] in FORWARD:
            raw = text.encode() if isinstance(text, str) else text
            self.hub.publish(Frame(_command(client), 0, now_ms(), raw))
            return
        await super().handle(client, text, msg)  # parsed once: skeleton frames are most of the traffic

    async def mesh_json(self, mesh_id: int) -> bytes | None:
        if mesh_id != self.scene.mesh_id:
            return None
        cache = getattr(self, "_mesh_cache", None)
        if cache is None or cache[0] != mesh_id:
            self._mesh_cache = cache = (mesh_id, await fetch(self.hub, {"mesh": mesh_id}))
        return cache[1]

    async def stop_recording(self) -> dict:
        result = json.loads(_answer(await self.hub.request(TAKES, b"stop", timeout=120)))
        folder = self.takes_dir / str(result["take"])
        folder.mkdir(parents=True, exist_ok=True)
        for href in result["files"].values():
            name = href.rsplit("/", 1)[-1]
            (folder / name).write_bytes(await fetch(self.hub, {"take": result["take"], "name": name}, 60))
        return result

    def start_job(self, name: str, data: bytes, loop: asyncio.AbstractEventLoop,
                  scan_options: dict | None = None) -> Job:
        """Send the upload to the scene in chunks; the local job follows the scene's job."""
        job = Job(next(self._ids), name)
        self.jobs[job.id] = job
        loop.create_task(self._upload(job, data, scan_options or {}))
        return job

    async def _upload(self, job: Job, data: bytes, scan_options: dict) -> None:
        try:
            count = max(1, -(-len(data) // CHUNK))
            upload = f"{id(job)}-{job.id}"
            remote = None
            for index in range(count):
                job.stage, job.fraction = "sending to the scene", 0.05 * index / count
                head = {"upload": upload, "name": job.name, "part": index, "parts": count, "scan": scan_options}
                reply = _answer(await self.hub.request(
                    UPLOAD, json.dumps(head).encode() + b"\n" + data[index * CHUNK:(index + 1) * CHUNK], 30))
                remote = json.loads(reply).get("job")
            while True:
                status = json.loads(_answer(await self.hub.request(JOBS, json.dumps({"job": remote}).encode())))
                job.stage, job.fraction, job.error = status["stage"], status["fraction"], status["error"]
                if status["done"]:
                    job.done = True
                    return
                await asyncio.sleep(0.25)
        except KinetreError as exc:
            job.error, job.stage, job.done = f"{job.name}: {exc}", "failed", True


# --- the scene side ------------------------------------------------------------------------------------
async def serve_scene(mesh_path: str | None, url: str, room: str = "main", token: str | None = None,
                      nodes: int = 128, sample_motion: bool = False, started=None, nkey: str | None = None) -> None:
    """`kinetre scene`: run until cancelled. `started(studio)` is called once it serves."""
    await probe_nats(url, room, token, nkey)  # a refusal is reported before the mesh is loaded
    path = mesh_path or str(data_path("spot.obj"))
    mesh, graph = await asyncio.to_thread(prepare_mesh, path, nodes)
    worker = SolveWorker()
    await worker.start()
    # connected only once the scene exists: nobody may hear of it before it subscribes (see below)
    bus = NatsChannels(room)
    studio = Studio(bus, Scene(bus, mesh, graph, Path(path).name, solver=worker), nodes=nodes)
    await bus.start(url, token, name="kinetre-scene", nkey=nkey)
    if sample_motion and mesh_path is None:
        studio.player = sample_player(bus)
    scene = studio.scene
    uploads: dict[str, list[bytes]] = {}

    async def command(frame: Frame) -> None:
        client = frame.subject.rsplit(".", 1)[-1]
        studio.stats.setdefault(client, ClientStats())
        try:
            kind = parse_message(frame.data).get("type")
        except ProtocolError:
            kind = None
        if kind == "bye":
            studio.stats.pop(client, None)
            scene.forget(client)
        elif kind == "record":
            scene.start_recording()
        else:
            await studio.handle(client, frame.data)

    async def files(data: bytes) -> bytes:
        what = json.loads(data)
        if "mesh" in what:
            payload = await studio.mesh_json(int(what["mesh"]))
            if payload is None:
                raise KinetreError(f"mesh {what['mesh']} is not loaded")
        else:
            take = studio.takes_dir / str(int(what["take"]))
            file = take / Path(str(what["name"])).name
            if not file.is_file():
                raise KinetreError(f"no file {what['name']} in take {what['take']}")
            payload = file.read_bytes()
        return _chunked(payload, int(what["chunk"]))

    async def takes(data: bytes) -> bytes:
        return json.dumps(await studio.stop_recording()).encode()

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
        job = studio.start_job(head["name"], b"".join(uploads.pop(head["upload"])), asyncio.get_running_loop(),
                               head.get("scan") or None)
        return json.dumps({"job": job.id}).encode()

    async def jobs(data: bytes) -> bytes:
        job = studio.jobs.get(json.loads(data)["job"])
        if job is None:
            raise KinetreError("no such job")
        return json.dumps({"stage": job.stage, "fraction": job.fraction, "error": job.error,
                           "done": job.done}).encode()

    async def beat() -> None:
        while True:
            await asyncio.sleep(BEAT)
            scene.publish_state()
            if scene.rig is None:  # idle: gateways that joined late still get the pose
                bus.publish(Frame(TRANSFORMS, scene.seq, now_ms(), scene.transforms_block()))

    await bus.listen("kinetre.command.*", command)
    for subject, handler in ((FILES, files), (TAKES, takes), (UPLOAD, upload), (JOBS, jobs)):
        await bus.serve(subject, handler)
    loop = asyncio.get_running_loop()
    tasks = [loop.create_task(scene.run()), loop.create_task(beat())]
    if studio.player is not None:
        tasks.append(loop.create_task(studio.player.run()))
        await asyncio.sleep(0.1)
        await studio.start_sample()
    await asyncio.sleep(0.05)  # the scene's task subscribes to the skeletons when it first runs
    await bus.ready()  # …and the server has it before anyone hears that the scene is up
    scene.publish_state()
    freeze_heap()
    if started is not None:
        started(studio)
    try:
        await asyncio.gather(*tasks)
    finally:
        for task in tasks:
            task.cancel()
        worker.close()
        await bus.close()


def run_scene(mesh_path: str | None, url: str, room: str = "main", token: str | None = None, nodes: int = 128,
              sample_motion: bool = False, nkey: str | None = None) -> None:
    """What `kinetre scene` runs: serve until interrupted. Raises KinetreError (NetworkError) on bad input."""
    def started(studio) -> None:
        print(f"Kinetre scene: {studio.scene.name} ({studio.scene.graph.node_count} nodes) in room {room!r} "
              f"on {url} (Ctrl+C to stop)", flush=True)
    main = serve_scene(mesh_path, url, room, token, nodes, sample_motion, started, nkey)
    try:  # uvloop, as uvicorn runs the studio (uvicorn[standard] installs it): each message's hops are cheaper
        import uvloop
    except ImportError:
        asyncio.run(main)
    else:
        uvloop.run(main)
