"""The studio server: Starlette routes around one `Scene`, the embedded `Hub` and the built page.

    GET  /                     the page (web/ built into static/)
    WS   /ws                   capture clients and viewers (protocol.py)
    GET  /api/state            the scene state (JSON)
    GET  /api/mesh/{id}        the current mesh with its skinning data (JSON, base64 arrays)
    POST /api/mesh?name=F      upload a mesh file (OBJ/PLY/STL/GLB…): a job that loads it and builds the graph;
                               a .zip of RGB-D frames (TUM or Redwood layout) is scanned into a mesh first
                               (&segment=plane|none, &voxel=metres)
    GET  /api/jobs/{id}        a job's stage, progress fraction and readable error
    POST /api/voice?client=C   16 kHz mono WAV: recognised offline, "possess"/"release"/subset applied for C
    POST /api/record/start     start recording a take; /api/record/stop ends it and exports GLB, BVH, stream
                               and the node transforms the page replays the physics from
    GET  /api/takes/{id}/{f}   a file of a recorded take
    POST /api/jointmap?name=F  a joint map (JSON, docs/joint-maps.md): the n-th user to possess drives with the
                               joints its n-th source keeps; DELETE /api/jointmap clears it
    /api/avatar, /api/avatars/…  rigged humanoid avatars beside the possessed mesh (avatars.py)
"""
from __future__ import annotations

import asyncio
import base64
import contextlib
import itertools
import json
import os
import secrets
import shutil
import tempfile
import threading
import webbrowser
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from ..errors import KinetreError
from ..graph.build import build_graph
from ..mesh.load import load_mesh
from ..mesh.mesh import Mesh
from ..physics.spheres import studio_packing
from .access import TokenGate, check_bind
from .avatars import Shelf, avatar_routes
from .channels import Frame, Hub
from .face_routes import face_routes
from .fanout import Framing, RawSockets, raw_socket
from .natsbus import NatsChannels
from .placement import standing_mesh
from .protocol import ProtocolError, parse_message, parse_skeleton, with_client
from .scene import (SKELETON_PREFIX, SKELETONS, STATE, TRANSFORMS, Scene, check_subset, client_subject, now_ms,
                    resample, skeleton_subject)
from .solve_worker import SolveWorker, freeze_heap
from .uploads import read_upload

NODES = 128  # graph size for meshes loaded in the studio (the paper's default)
TAKE_FPS = 30.0
MAX_UPLOAD = 200 * 1024 * 1024
SAMPLE_CLIENT = "sample"


def data_path(name: str) -> Path:
    """A file shipped in kinetre/data (the sample mesh and motion)."""
    return Path(str(resources.files("kinetre") / "data" / name))


def static_dir() -> Path:
    return Path(str(resources.files("kinetre") / "studio" / "static"))


def prepare_mesh(path: str, nodes: int = NODES, progress=lambda stage, fraction: None):
    """Load, stand in metres and build the graph: (Mesh, DeformationGraph). Raises KinetreError."""
    progress("reading", 0.05)
    mesh = standing_mesh(load_mesh(path))
    progress("building graph", 0.3)
    graph = build_graph(mesh, nodes=nodes, seed=0)
    progress("packing physics spheres", 0.9)
    studio_packing(mesh)  # cached: the payload is then ready without blocking the server's event loop
    progress("ready", 1.0)
    return mesh, graph


def mesh_payload(mesh: Mesh, graph, mesh_id: int, name: str) -> dict:
    """What the page needs to build a SkinnedMesh and its physics spheres: little-endian arrays as base64."""
    def b64(a, dtype):
        return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode()
    return {"id": mesh_id, "name": name, "vertexCount": int(len(mesh.vertices)),
            "nodeCount": graph.node_count,
            "positions": b64(mesh.vertices, "<f4"), "normals": b64(mesh.normals, "<f4"),
            "faces": b64(mesh.faces, "<u4"), "skinIndex": b64(graph.vertex_nodes, "<u2"),
            "skinWeight": b64(graph.vertex_weights, "<f4"), "nodes": b64(graph.nodes, "<f4"),
            "nodeNormals": b64(graph.normals, "<f4"),
            "spheres": b64(studio_packing(mesh).centres, "<u4"), "sphereRadius": studio_packing(mesh).radius}


@dataclass
class Job:
    id: int
    name: str
    stage: str = "uploaded"
    fraction: float = 0.0
    error: str = ""
    done: bool = False


@dataclass
class ClientStats:
    received: int = 0
    malformed: int = 0
    last_seq: int = -1
    skeletons: bool = False  # forward other users' skeleton frames to this client
    window: int = 0  # flow control: at most this many messages sent and not yet acknowledged (0 = off)
    sent: int = 0
    acked: int = 0
    ack: asyncio.Event = field(default_factory=asyncio.Event)
    transforms_sent: int = 0
    transforms_skipped: int = 0  # scene frames this client never got: replaced by newer ones (latest wins)
    transforms_seq: int = 0
    sub: object = None  # the connection's Subscription


@dataclass
class Studio:
    """Everything one studio server runs: hub, scene, sample player, upload jobs and takes."""

    hub: Hub
    scene: Scene
    player: object | None = None
    nodes: int = NODES  # graph size for uploaded meshes
    jobs: dict[int, Job] = field(default_factory=dict)
    takes_dir: Path = field(default_factory=lambda: Path(tempfile.mkdtemp(prefix="kinetre-takes-")))
    stats: dict[str, ClientStats] = field(default_factory=dict)
    _ids: itertools.count = field(default_factory=lambda: itertools.count(1))
    _takes: itertools.count = field(default_factory=lambda: itertools.count(1))

    # --- messages from a client ------------------------------------------------------------------------
    async def handle(self, client: str, text: str | bytes, msg: dict | None = None) -> None:
        """Apply one client message (`msg`: `text` already parsed); malformed ones are answered with an error,
        never fatal."""
        stats = self.stats[client]
        try:
            msg = parse_message(text) if msg is None else msg
            kind = msg["type"]
            if kind == "skeleton":
                seq, t, skeleton = parse_skeleton(msg)
                stats.received += 1
                stats.last_seq = seq
                self.hub.publish(Frame(skeleton_subject(client), seq, t, with_client(text, client),
                                       (seq, t, skeleton)))
            elif kind == "possess":
                if self.player is not None and client != SAMPLE_CLIENT:
                    await self.stop_sample()  # a live user takes over from the sample motion
                await self.scene.possess(client, check_subset(msg.get("subset")))
            elif kind == "release":
                await self.scene.release(client)
            elif kind == "subset":
                await self.scene.set_subset(client, check_subset(msg.get("subset")))
            elif kind == "place":
                pos = msg.get("position", [0, 0, 0])
                if not isinstance(pos, list):
                    raise ProtocolError("position must be a list of 3 numbers")
                self.scene.place(float(msg.get("scale", 1.0)), pos, float(msg.get("yaw", 0.0)))
            elif kind == "fit":
                self.scene.fit(client)
            elif kind == "player":
                await (self.start_sample() if msg.get("on") else self.stop_sample())
            elif kind == "subscribe":
                stats.skeletons = bool(msg.get("skeletons"))
                if stats.skeletons and stats.sub is not None:
                    stats.sub.add(SKELETONS)  # only now: a watcher that never asks costs nothing per frame
                window = msg.get("window", 0)
                if not isinstance(window, int) or not 0 <= window <= 256:
                    raise ProtocolError(f"window must be an integer 0..256, got {window!r}")
                stats.window = window
                stats.ack.set()
            elif kind == "ack":
                received = msg.get("received")
                if not isinstance(received, int) or received < 0:
                    raise ProtocolError(f"ack needs 'received', a message count, got {received!r}")
                stats.acked = max(stats.acked, min(received, stats.sent))
                stats.ack.set()
            elif kind == "stats":
                self.reply(client, {"type": "stats", "client": client, "received": stats.received,
                                    "malformed": stats.malformed, "last_seq": stats.last_seq,
                                    "transforms_sent": stats.transforms_sent,
                                    "transforms_skipped": stats.transforms_skipped})
            else:
                raise ProtocolError(f"unknown message type {kind!r}")
        except ProtocolError as exc:
            stats.malformed += 1
            self.reply(client, {"type": "error", "message": f"bad message: {exc}"})
        except (KinetreError, TypeError, ValueError) as exc:
            self.reply(client, {"type": "error", "message": str(exc)})

    async def mesh_json(self, mesh_id: int) -> bytes | None:
        """The mesh payload (JSON bytes) if `mesh_id` is the loaded mesh."""
        scene = self.scene
        if mesh_id != scene.mesh_id:
            return None
        return json.dumps(mesh_payload(scene.mesh, scene.graph, scene.mesh_id, scene.name)).encode()

    def reply(self, client: str, message: dict) -> None:
        self.hub.publish(Frame(client_subject(client), 0, now_ms(), json.dumps(message).encode()))

    # --- the sample motion -----------------------------------------------------------------------------
    async def start_sample(self) -> None:
        if self.player is None:
            return
        self.player.playing = True
        self.player.publish(0, now_ms())
        await asyncio.sleep(0.05)  # let the scene receive the first frame
        if not any(u.bind is not None for c, u in self.scene.users.items() if c != SAMPLE_CLIENT):
            self.scene.fit(SAMPLE_CLIENT)
            try:
                await self.scene.possess(SAMPLE_CLIENT)
            except KinetreError:
                pass  # a mesh the walk cannot reach just stands still

    async def stop_sample(self) -> None:
        if self.player is not None and self.player.playing:
            self.player.playing = False
            await self.scene.release(SAMPLE_CLIENT)

    # --- mesh uploads ----------------------------------------------------------------------------------
    def start_job(self, name: str, data: bytes, loop: asyncio.AbstractEventLoop,
                  scan_options: dict | None = None) -> Job:
        """Prepare an uploaded mesh in a worker thread; a .zip of RGB-D frames is scanned into one first."""
        job = Job(next(self._ids), name)
        self.jobs[job.id] = job
        folder = Path(tempfile.mkdtemp(prefix="kinetre-upload-"))
        path = folder / (Path(name).name or "mesh")
        path.write_bytes(data)

        def progress(stage: str, fraction: float) -> None:
            job.stage, job.fraction = stage, fraction

        def work() -> None:
            mesh_path = path
            try:
                if path.suffix.lower() == ".zip":
                    from ..scan.pipeline import scan_zip
                    progress("scanning RGB-D frames", 0.05)
                    result = scan_zip(path, folder / (path.stem + ".ply"), **(scan_options or {}))
                    mesh_path = Path(result.mesh_path)
                mesh, graph = prepare_mesh(str(mesh_path), self.nodes, progress=progress)
            except KinetreError as exc:
                job.error = str(exc).replace(str(folder) + os.sep, "")
                job.stage, job.done = "failed", True
                return
            except Exception as exc:  # a bug must still reach the page as a message, not a dead bar
                job.error = f"{name}: could not prepare the mesh ({type(exc).__name__}: {exc})"
                job.stage, job.done = "failed", True
                return
            finally:
                shutil.rmtree(folder, ignore_errors=True)

            def swap() -> None:
                self.player_off_for_new_mesh()
                self.scene.set_mesh(mesh, graph, mesh_path.name if mesh_path != path else Path(name).name)
                job.done = True

            loop.call_soon_threadsafe(swap)

        threading.Thread(target=work, daemon=True).start()
        return job

    def player_off_for_new_mesh(self) -> None:
        if self.player is not None:
            self.player.playing = False

    # --- takes -----------------------------------------------------------------------------------------
    async def stop_recording(self) -> dict:
        take = resample(self.scene.stop_recording(), TAKE_FPS)
        if not take:
            raise KinetreError("the take is empty: possess the mesh (or play the sample) while recording")
        take_id = next(self._takes)
        folder = self.takes_dir / str(take_id)
        folder.mkdir(parents=True)
        scene = self.scene
        files = await asyncio.to_thread(export_take, folder, scene.mesh, scene.graph, take, TAKE_FPS)
        return {"take": take_id, "frames": len(take), "fps": TAKE_FPS,
                "files": {k: f"/api/takes/{take_id}/{v}" for k, v in files.items()}}


def export_take(folder: Path, mesh, graph, take, fps: float) -> dict[str, str]:
    """Write the take as GLB (the mesh animated), node transforms (physics replay), BVH and the skeleton
    stream of its first user."""
    from ..export.gltf import write_gltf
    files = {}
    write_gltf(folder / "take.glb", mesh, graph, [f.pose for f in take], fps)
    files["glb"] = "take.glb"
    from ..physics.take import write_take_transforms  # the page replays the physics from these
    write_take_transforms(folder / "take.transforms", graph, [f.pose for f in take], fps)
    files["transforms"] = "take.transforms"
    clients = [c for c in take[0].skeletons]
    if clients:
        frames = [f.skeletons.get(clients[0]) for f in take]
        frames = [s for s in frames if s is not None]
        from ..export.bvh import write_bvh
        write_bvh(folder / "take.bvh", frames, fps)
        files["bvh"] = "take.bvh"
        from ..motion import stream
        stream.write_stream(folder / "take.kinetre.jsonl", frames, fps)
        files["stream"] = "take.kinetre.jsonl"
    return files


def create_app(mesh_path: str | None = None, nodes: int = NODES, sample_motion: bool = True, *,
               nats: str | None = None, room: str = "main", token: str | None = None,
               remote_scene: bool = False, nkey: str | None = None) -> Starlette:
    """The studio as an ASGI app (tests run it under uvicorn on 127.0.0.1).

    With `nats` (a NATS server URL) the channels are that server's subjects for `room` (natsbus.py);
    with `remote_scene` too, the scene is a `kinetre scene` process elsewhere and this server is only
    the pages' gateway to it (remote.py). A `token` is required from every client (access.py); `nkey`, the
    room's nkey seed file, then authenticates to NATS instead of the token.
    """
    hub = NatsChannels(room) if nats else Hub()
    solver = None
    if remote_scene:
        if not nats:
            raise KinetreError("a remote scene needs a NATS server (--nats URL)")
        from .remote import GatewayStudio, SceneMirror
        studio = GatewayStudio(hub, SceneMirror(hub), nodes=nodes)
    else:
        path = mesh_path or str(data_path("spot.obj"))
        mesh, graph = prepare_mesh(path, nodes)
        solver = SolveWorker()  # the solve never holds the server's interpreter
        studio = Studio(hub, Scene(hub, mesh, graph, Path(path).name, solver=solver), nodes=nodes)
        if sample_motion and mesh_path is None:
            studio.player = sample_player(hub)
    shelf = Shelf()
    clients = itertools.count(1)
    prefix = f"{secrets.token_hex(2)}-" if nats else ""  # client names unique across studios of a room
    framing = Framing()  # each transform block framed once for all pages
    tasks: list[asyncio.Task] = []

    @contextlib.asynccontextmanager
    async def lifespan(app):
        loop = asyncio.get_running_loop()
        if nats:
            await hub.start(nats, token, name="kinetre-studio", nkey=nkey)
        if solver is not None:
            await solver.start()
        tasks.append(loop.create_task(studio.scene.run()))
        if studio.player is not None:
            tasks.append(loop.create_task(studio.player.run()))
            await studio.start_sample()
        freeze_heap()  # start-up's objects (mesh, kernels, modules) out of every later full collection
        yield
        for task in tasks:
            task.cancel()
        if solver is not None:
            solver.close()
        if nats:
            await hub.close()
        shutil.rmtree(studio.takes_dir, ignore_errors=True)
        shelf.close()

    async def ws_endpoint(ws: WebSocket) -> None:
        await ws.accept()
        client = f"{prefix}c{next(clients)}"
        studio.stats[client] = stats = ClientStats()
        sub = stats.sub = hub.subscribe(urgent=(TRANSFORMS, STATE, client_subject(client)))
        await ws.send_text(json.dumps({"type": "welcome", "client": client,
                                       "channel": skeleton_subject(client)}))
        await ws.send_text(json.dumps(studio.scene.state()))
        block = studio.scene.transforms_block()  # None while a remote scene has not been heard yet
        if block is not None:
            await ws.send_bytes(block)
            stats.transforms_sent = 1  # a count of every transform block the page got, this one included
        stats.sent = 3 if block is not None else 2

        def count_transforms(frame: Frame) -> None:
            stats.sent += 1  # counted before any await: an ack may arrive before the send returns
            if stats.transforms_seq and frame.seq > stats.transforms_seq + 1:
                stats.transforms_skipped += frame.seq - stats.transforms_seq - 1
            stats.transforms_seq, stats.transforms_sent = frame.seq, stats.transforms_sent + 1

        raw = raw_socket(ws.scope)
        if raw is not None:
            def direct(frame: Frame) -> bool:
                """A transform block written in the publisher's call when the page can take it now."""
                if frame.subject != TRANSFORMS or not raw.ready() or (
                        stats.window and stats.sent - stats.acked >= stats.window):
                    return False  # send_loop delivers it (latest wins) once the page can take it
                count_transforms(frame)
                raw.write(framing(frame.data))
                return True
            sub.direct = direct

        async def send_loop() -> None:
            # One sender per connection: a slow viewer only ever has the newest frame per subject waiting.
            # With a window, it also never has more than `window` messages in the network buffers, which
            # would otherwise hold seconds of stale frames for a page whose main thread is busy.
            while True:
                while stats.window and stats.sent - stats.acked >= stats.window:
                    stats.ack.clear()
                    await stats.ack.wait()
                frame = await sub.next()
                if frame is None:
                    return
                skeleton = frame.subject.startswith(SKELETON_PREFIX)
                if skeleton and (not stats.skeletons or frame.subject.endswith("." + client)):
                    continue  # other users' skeletons only for viewers that asked; a page draws its own
                if frame.subject == TRANSFORMS:
                    count_transforms(frame)
                    await ws.send_bytes(frame.data)
                else:
                    stats.sent += 1  # counted before the await: an ack may arrive before the send returns
                    await ws.send_text(frame.data.decode())

        sender = asyncio.get_running_loop().create_task(send_loop())
        try:
            while True:
                message = await ws.receive()
                if message["type"] == "websocket.disconnect":
                    break
                data = message.get("text")
                if data is None:
                    data = message.get("bytes") or b""
                await studio.handle(client, data)
        except WebSocketDisconnect:
            pass
        finally:
            sender.cancel()
            sub.close()
            studio.stats.pop(client, None)
            studio.scene.forget(client)

    async def state(request: Request) -> Response:
        return JSONResponse(studio.scene.state())

    async def mesh_get(request: Request) -> Response:
        payload = await studio.mesh_json(int(request.path_params["mesh_id"]))
        if payload is None:
            return JSONResponse({"error": f"mesh {request.path_params['mesh_id']} is not loaded"}, 404)
        return Response(payload, media_type="application/json")

    async def mesh_post(request: Request) -> Response:
        name, data, refused = await read_upload(request, "mesh", MAX_UPLOAD)
        if refused is not None:
            return refused
        scan_options = {}
        if name.lower().endswith(".zip"):  # the "Scan" entry: RGB-D frames, segmented by plane by default
            segment = request.query_params.get("segment", "plane")
            if segment not in ("plane", "none"):
                return JSONResponse({"error": f"{name}: segment must be 'plane' or 'none', got {segment!r}"}, 400)
            try:
                voxel = float(request.query_params.get("voxel", "0.01"))
            except ValueError:
                return JSONResponse({"error": f"{name}: voxel must be a number in metres"}, 400)
            scan_options = {"segment": None if segment == "none" else segment, "voxel": voxel}
        job = studio.start_job(name, data, asyncio.get_running_loop(), scan_options)
        return JSONResponse({"job": job.id}, 202)

    async def job_get(request: Request) -> Response:
        job = studio.jobs.get(int(request.path_params["job_id"]))
        if job is None:
            return JSONResponse({"error": "no such job"}, 404)
        return JSONResponse({"job": job.id, "name": job.name, "stage": job.stage, "fraction": job.fraction,
                             "error": job.error, "done": job.done,
                             "mesh": studio.scene.mesh_id if job.done and not job.error else None})

    voice_decoder: dict = {}

    async def voice_post(request: Request) -> Response:
        client = request.query_params.get("client", "")
        data = await request.body()
        from .voice import Recogniser, recognise
        try:
            # one decoder for the studio's lifetime: loading it costs ~50 ms per utterance otherwise
            if voice_decoder.get("recogniser") is None:
                voice_decoder["recogniser"] = await asyncio.to_thread(Recogniser)
        except KinetreError as exc:  # pocketsphinx missing: the page says how to install it
            return JSONResponse({"error": str(exc)}, 503)
        try:
            command = await asyncio.to_thread(recognise, data, 16000, recogniser=voice_decoder["recogniser"])
        except KinetreError as exc:
            return JSONResponse({"error": str(exc)}, 400)
        if command is None:
            return JSONResponse({"command": None})
        result = {"verb": command.verb, "subset": command.subset, "text": command.text}
        if client in studio.stats:
            try:
                if command.verb == "possess":
                    await studio.handle(client, json.dumps({"type": "possess", "subset": command.subset}))
                elif command.verb == "release":
                    await studio.handle(client, json.dumps({"type": "release"}))
                elif command.subset is not None:
                    await studio.handle(client, json.dumps({"type": "subset", "subset": command.subset}))
            except KinetreError as exc:
                return JSONResponse({"command": result, "error": str(exc)})
        return JSONResponse({"command": result})

    async def record_start(request: Request) -> Response:
        studio.scene.start_recording()
        return JSONResponse({"recording": True})

    async def record_stop(request: Request) -> Response:
        try:
            return JSONResponse(await studio.stop_recording())
        except KinetreError as exc:
            return JSONResponse({"error": str(exc)}, 400)

    async def take_get(request: Request) -> Response:
        name = request.path_params["name"]
        folder = studio.takes_dir / str(int(request.path_params["take_id"]))
        path = folder / Path(name).name
        if not path.is_file():
            return JSONResponse({"error": f"no file {name} in take {request.path_params['take_id']}"}, 404)
        return FileResponse(path, filename=f"kinetre-{request.path_params['take_id']}-{path.name}")

    async def joint_map(request: Request) -> Response:
        from ..motion.jointmap import parse_joint_map
        if request.method == "DELETE":
            studio.scene.joint_map = None
        else:
            name = Path(request.query_params.get("name", "joint map")).name
            try:
                studio.scene.joint_map = parse_joint_map(json.loads(await request.body()), name)
            except ValueError as exc:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
                return JSONResponse({"error": f"{name}: not valid JSON ({exc})"}, 400)
            except KinetreError as exc:
                return JSONResponse({"error": str(exc)}, 400)
        studio.scene.publish_state()
        return JSONResponse({"joint_map": studio.scene.state()["joint_map"]})

    routes = [
        WebSocketRoute("/ws", ws_endpoint),
        Route("/api/jointmap", joint_map, methods=["POST", "DELETE"]),
        Route("/api/state", state),
        Route("/api/mesh/{mesh_id:int}", mesh_get),
        Route("/api/mesh", mesh_post, methods=["POST"]),
        Route("/api/jobs/{job_id:int}", job_get),
        Route("/api/voice", voice_post, methods=["POST"]),
        Route("/api/record/start", record_start, methods=["POST"]),
        Route("/api/record/stop", record_stop, methods=["POST"]),
        Route("/api/takes/{take_id:int}/{name}", take_get),
        *avatar_routes(shelf),
        *face_routes(),
    ]
    static = static_dir()
    if (static / "index.html").is_file():
        routes.append(Mount("/", StaticFiles(directory=static, html=True)))
    else:
        async def not_built(request: Request) -> Response:
            return Response("The studio page is not built: run `make web` (cd web && npm ci && npm run build).",
                            503, media_type="text/plain")
        routes.append(Route("/", not_built))
    app = Starlette(routes=routes, lifespan=lifespan,
                    middleware=[Middleware(RawSockets), Middleware(TokenGate, room=room, token=token)])
    app.state.studio = studio
    return app


def sample_player(hub: Hub):
    """The CMU walk (shipped in kinetre/data) as a looping capture client, or None if it cannot load."""
    from .player import MotionPlayer, decimate, in_place
    try:
        from ..motion.bvh import load_bvh
        take = load_bvh(str(data_path("cmu_12_01_walk.bvh")))
        frames = [take.frame(i) for i in range(len(take))]
        fps = float(take.fps)
    except (ImportError, KinetreError):
        return None
    frames, fps = decimate(in_place(frames), fps)
    return MotionPlayer(hub, frames, fps, SAMPLE_CLIENT)


def run_studio(mesh_path: str | None, host: str = "127.0.0.1", port: int = 8000, open_browser: bool = True,
               nodes: int = NODES, sample_motion: bool = True, *, nats: str | None = None, room: str = "main",
               token: str | None = None, remote_scene: bool = False, nkey: str | None = None) -> None:
    """Serve the studio until interrupted (what `kinetre studio` runs). Raises KinetreError on a bad mesh,
    an unreachable or refusing NATS server, or a non-loopback `host` without a `token`.

    Without `mesh_path` the sample mesh (Spot) is loaded and, with `sample_motion`, a CMU walk drives it.
    """
    import uvicorn
    check_bind(host, token)
    if nats:
        asyncio.run(probe_nats(nats, room, token, nkey))  # a clear error now rather than a traceback at startup
    app = create_app(mesh_path, nodes, sample_motion, nats=nats, room=room, token=token, remote_scene=remote_scene,
                     nkey=nkey)
    url = f"http://{'127.0.0.1' if host in ('0.0.0.0', '::') else host}:{port}/"
    if token:
        url += f"?token={token}"
    if open_browser:
        threading.Timer(1.0, webbrowser.open, args=(url,)).start()
    print(f"Kinetre studio on {url} (Ctrl+C to stop)", flush=True)
    # No permessage-deflate: a 253-node transform block deflates only from 12.2 to 11.4 kB, and deflating it
    # once per viewer (one deflate context per connection) was the fan-out's main cost (~0.4-0.9 ms a send).
    uvicorn.run(app, host=host, port=port, log_level="warning", ws_max_size=1 << 20, ws_per_message_deflate=False)


async def probe_nats(url: str, room: str, token: str | None, nkey: str | None = None) -> None:
    """Connect to the room once and leave; raises NetworkError with the reason."""
    bus = await NatsChannels.connect(url, room, token, name="kinetre-probe", nkey=nkey)
    await bus.close()
