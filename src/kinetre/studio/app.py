"""The studio server: one scene host, its bus, the viewers' WebSocket and the HTTP routes, around the page.

The data path through it: a page's skeleton frames come in on its WebSocket (viewer.py) and go onto the
bus (the embedded `Hub`, or a NATS room: natsbus.py) → the scene solves (scene/, in this process through
`LocalScene`, or in a `kinetre scene` process that a `remote.GatewayScene` mirrors) → its transform blocks
and state go back out through the bus to every viewer.

    GET  /                     the page (web/ built into static/)
    GET  /models/NAME.task     the tracking models, wherever `model_path` finds them (an installed
                               package's page carries none: they are in the user's cache)
    WS   /ws                   capture clients and viewers (viewer.py, protocol.py)
    /api/…                     state, meshes, jobs, voice, takes, joint maps (routes.py)
    /api/avatar, /api/avatars/…  rigged humanoid avatars beside the possessed mesh (avatars.py)
    /api/face/…                face puppets (face_routes.py)
    UDP (optional)             VMC out: every avatar's pose to a receiver (vmc_out.py); VMC in: performers as
                               users (vmc_in.py)
"""
from __future__ import annotations

import asyncio
import contextlib
import json
import secrets
import threading
import webbrowser
from importlib import resources
from pathlib import Path

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket

from ..errors import KinetreError
from ..mesh.load import load_mesh
from ..motion.models import MODELS, model_path
from .access import TokenGate, check_bind
from .avatars import Shelf, avatar_routes
from .channels import Channels, Hub
from .face_routes import face_routes
from .fanout import Framing, RawSockets
from .host import LocalScene, SceneHost, apply
from .meshes import NODES, data_path, prepare_upright
from .natsbus import NatsChannels, probe_nats
from .player import sample_player
from .routes import api_routes
from .scene import Scene
from .scene.solve_worker import SolveWorker, freeze_heap
from .sessions import RESUME_S, Sessions
from .viewer import Viewer
from ..vmc.receive import check_listen
from .vmc_in import VmcUsers
from .vmc_out import VmcOut


def static_dir() -> Path:
    return Path(str(resources.files("kinetre") / "studio" / "static"))


async def model_get(request: Request) -> Response:
    name = request.path_params["name"]
    if name not in MODELS:
        return Response(f"unknown model {name}", 404, media_type="text/plain")
    try:
        path = model_path(name)
    except KinetreError as e:
        return Response(str(e), 404, media_type="text/plain")
    return FileResponse(path, media_type="application/octet-stream")


def create_app(mesh_path: str | None = None, nodes: int = NODES, sample_motion: bool = True, *,
               nats: str | None = None, room: str = "main", token: str | None = None,
               remote_scene: bool = False, nkey: str | None = None, vmc: tuple[str, int] | None = None,
               vmc_listen: tuple[str, int] | None = None, clean: bool = True, contact: bool = False,
               resume_s: float = RESUME_S) -> Starlette:
    """The studio as an ASGI app (tests run it under uvicorn on 127.0.0.1).

    With `nats` (a NATS server URL) the channels are that server's subjects for `room` (natsbus.py);
    with `remote_scene` too, the scene is a `kinetre scene` process elsewhere and this server is only
    the pages' gateway to it (remote.py). A `token` is required from every client (access.py); `nkey`, the
    room's nkey seed file, then authenticates to NATS instead of the token. `vmc` (host, port): the avatars
    send VMC there (vmc_out.py); `vmc_listen` (host, port): VMC performers there become users (vmc_in.py).
    `clean`: camera users' body frames are smoothed and their feet held before the solve (kinetre.motion.cleanup);
    `contact`: mocap users' feet are held too (the sample player, VMC performers; see `Scene`).
    `resume_s`: how long a page whose connection dropped keeps its user for its reconnect (sessions.py).
    """
    hub = NatsChannels(room) if nats else Hub()
    host: SceneHost
    if remote_scene:
        if not nats:
            raise KinetreError("a remote scene needs a NATS server (--nats URL)")
        from .remote import GatewayScene
        host = GatewayScene(hub)
    else:
        path = mesh_path or str(data_path("spot.obj"))
        raw = load_mesh(path)
        mesh, graph, upright = prepare_upright(raw, path, nodes)
        scene = Scene(hub, mesh, graph, Path(path).name, solver=SolveWorker(),  # the solve never holds the server
                      upright=upright, new_solver=SolveWorker, clean=clean, contact=contact)
        player = sample_player(hub) if sample_motion and mesh_path is None else None
        host = LocalScene(hub, scene, player, nodes=nodes, source=(raw, Path(path).name))
    shelf = Shelf()
    viewers: dict[str, Viewer] = {}
    prefix = f"{secrets.token_hex(2)}-" if nats else ""  # client names unique across studios of a room
    sessions = Sessions(host.forget, prefix, resume_s)
    framing = Framing()  # each transform block and state framed once for all pages
    vmc_out = VmcOut(hub, shelf, *vmc) if vmc is not None else None
    vmc_users = VmcUsers(hub, possess_command(host, hub), *vmc_listen) if vmc_listen is not None else None
    bridges: list[asyncio.Task] = []

    @contextlib.asynccontextmanager
    async def lifespan(app):
        if nats:
            await hub.start(nats, token, name="kinetre-studio", nkey=nkey)
        await host.start()
        if vmc_out is not None:
            bridges.append(asyncio.get_running_loop().create_task(vmc_out.run()))
        if vmc_users is not None:
            await vmc_users.start()
        freeze_heap()  # start-up's objects (mesh, kernels, modules) out of every later full collection
        yield
        for task in bridges:
            task.cancel()
        if vmc_users is not None:
            vmc_users.close()
        await host.close()
        if nats:
            await hub.close()
        shelf.close()

    async def ws_endpoint(ws: WebSocket) -> None:
        await ws.accept()
        client, resume = sessions.open(ws.query_params.get("resume"))
        viewers[client] = viewer = Viewer(ws, client, hub, host, framing, f"{client}.{resume}")
        try:
            await viewer.run()
        finally:
            if viewers.get(client) is viewer:  # not taken over by the same page reconnecting
                del viewers[client]
            sessions.close(client, viewer.close_code)

    routes = [WebSocketRoute("/ws", ws_endpoint), *api_routes(host, hub, viewers.__contains__),
              *avatar_routes(shelf), *face_routes()]
    routes.append(Route("/models/{name}", model_get))
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
    app.state.host = host
    app.state.vmc_out, app.state.vmc_users = vmc_out, vmc_users
    return app


def possess_command(host: SceneHost, hub: Channels):
    """command(client, msg) for VMC performers: a page's command, as JSON through the one dispatch
    (`host.apply`); the failure, or None."""
    async def command(client: str, msg: dict) -> Exception | None:
        return await apply(host, hub, client, msg, json.dumps(msg).encode())
    return command


def run_studio(mesh_path: str | None, host: str = "127.0.0.1", port: int = 8000, open_browser: bool = True,
               nodes: int = NODES, sample_motion: bool = True, *, nats: str | None = None, room: str = "main",
               token: str | None = None, remote_scene: bool = False, nkey: str | None = None,
               vmc: tuple[str, int] | None = None, vmc_listen: tuple[str, int] | None = None,
               clean: bool = True, contact: bool = False) -> None:
    """Serve the studio until interrupted (what `kinetre studio` runs). Raises KinetreError on a bad mesh,
    an unreachable or refusing NATS server, a non-loopback `host` without a `token`, or a VMC port that
    cannot be listened on.

    Without `mesh_path` the sample mesh (Spot) is loaded and, with `sample_motion`, a CMU walk drives it.
    """
    import uvicorn
    check_bind(host, token)
    if nats:
        asyncio.run(probe_nats(nats, room, token, nkey))  # a clear error now rather than a traceback at startup
    if vmc_listen is not None:
        check_listen(*vmc_listen)
    app = create_app(mesh_path, nodes, sample_motion, nats=nats, room=room, token=token, remote_scene=remote_scene,
                     nkey=nkey, vmc=vmc, vmc_listen=vmc_listen, clean=clean, contact=contact)
    url = f"http://{'127.0.0.1' if host in ('0.0.0.0', '::') else host}:{port}/"
    if token:
        url += f"?token={token}"
    if open_browser:
        threading.Timer(1.0, webbrowser.open, args=(url,)).start()
    print(f"Kinetre studio on {url} (Ctrl+C to stop)", flush=True)
    # No permessage-deflate: a transform block hardly deflates, and deflating it once per viewer (one
    # deflate context per connection) was the fan-out's main cost.
    uvicorn.run(app, host=host, port=port, log_level="warning", ws_max_size=1 << 20, ws_per_message_deflate=False)

