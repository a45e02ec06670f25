"""Where the scene lives, as the studio's server sees it.

The server's routes and viewer connections talk to a `SceneHost`: the scene's state and newest transforms
for pages that connect, the commands people give it, its meshes, uploads and takes. `LocalScene` hosts a
`Scene` in this process (the studio on one machine, and the `kinetre scene` process); `remote.GatewayScene`
mirrors one that runs elsewhere and reaches it over NATS. Both answer a bad command on the client's reply
subject, never with an exception out of the connection.
"""
from __future__ import annotations

import asyncio
import json
import logging
import threading
from pathlib import Path
from typing import Protocol

from ..errors import KinetreError
from ..mesh.upright import AXES
from .channels import Channels, Frame, now_ms
from .jobs import Job, Jobs, prepare_upload
from .meshes import NODES, mesh_payload, prepare_upright
from .player import MotionPlayer, read_motion
from .protocol import (SAMPLE_CLIENT, ProtocolError, check_hand, check_subset, is_person_of, parse_mesh,
                       parse_person, parse_place, person_client)
from .recording import Takes, record_take
from .scene import Scene
from .subjects import client_subject

log = logging.getLogger("kinetre.studio")

SCENE_COMMANDS = ("possess", "release", "subset", "place", "fit", "player")  # what the scene itself applies
ANSWERED = (ProtocolError, KinetreError)  # the client's mistake: told to it, never fatal


class SceneHost(Protocol):
    """What the studio's server needs from the scene, wherever it runs."""

    jobs: Jobs
    takes: Takes

    @property
    def mesh_id(self) -> int: ...

    def state(self) -> dict: ...

    def transforms_blocks(self) -> list[bytes]:
        """Every mesh's current pose for a page that connects (none while nothing is known of them yet)."""

    async def command(self, client: str, msg: dict, raw: bytes) -> None:
        """Apply one of SCENE_COMMANDS (`msg`, parsed from `raw`); raises one of ANSWERED on bad input."""

    def forget(self, client: str) -> None: ...

    async def mesh_json(self, mesh_id: int) -> bytes | None:
        """The mesh payload (JSON bytes) if `mesh_id` is one of the scene's meshes."""

    def start_job(self, name: str, data: bytes, scan_options: dict | None = None, add: bool = False) -> Job:
        """Prepare an uploaded mesh: it replaces the first mesh, or with `add` joins the scene beside the
        others (the job's `mesh_id` once done)."""

    def set_up(self, up: str, mesh_id: int | None = None) -> Job:
        """Stand mesh `mesh_id` (None: the first) with its stored axis `up` (one of
        `kinetre.mesh.upright.AXES`) as +Y (the page's override of the up axis found on load): a job like an
        upload; KinetreError where that cannot be done (MeshError for an unknown mesh)."""

    async def remove_mesh(self, mesh_id: int) -> None:
        """Remove a mesh, releasing its possessors; MeshError if unknown, the only one, or being recorded."""

    def start_recording(self) -> None: ...

    async def stop_recording(self) -> dict:
        """End the take and export it into `takes`: {"take", "frames", "fps", "files"}; KinetreError if empty."""

    async def play_motion(self, name: str, data: bytes) -> dict:
        """Play an uploaded motion file in a loop as the sample motion: {"motion", "frames", "fps"};
        KinetreError for a file that does not read or a host that cannot play one."""

    def set_joint_map(self, joint_map) -> dict | None:
        """Use `joint_map` (a JointMap, or None to clear) for the next possessions; the state's joint_map."""

    async def start(self) -> None:
        """Start the host's tasks in the running event loop."""

    async def close(self) -> None: ...


def reply(hub: Channels, client: str, message: dict) -> None:
    """A message for one client only (its page gets it on its connection)."""
    hub.publish(Frame(client_subject(client), 0, now_ms(), json.dumps(message).encode()))


def answer_error(hub: Channels, client: str, exc: Exception) -> None:
    """Tell `client` what was wrong with its message: one of ANSWERED is its mistake, anything else the
    server's (logged with its traceback; the client only learns that its message was not carried out)."""
    if isinstance(exc, ProtocolError):
        message = f"bad message: {exc}"
    elif isinstance(exc, KinetreError):
        message = str(exc)
    else:
        log.error("a client's message failed in the server", exc_info=exc)
        message = f"the server failed on this message ({type(exc).__name__}): it is logged there"
    reply(hub, client, {"type": "error", "message": message})


async def apply(host: SceneHost, hub: Channels, client: str, msg: dict, raw: bytes) -> Exception | None:
    """Give the host one command from `client`: the one place scene commands are told apart from anything
    else a client sends, and their failures answered (see `answer_error`). The failure, or None."""
    try:
        if msg["type"] not in SCENE_COMMANDS:
            raise ProtocolError(f"unknown message type {msg['type']!r}")
        await host.command(client, msg, raw)
    except Exception as exc:  # the client's mistake, or the server's (logged): the connection goes on
        answer_error(hub, client, exc)
        return exc
    return None


class LocalScene:
    """A `Scene` in this process, with the sample motion, upload jobs and takes around it."""

    def __init__(self, hub: Channels, scene: Scene, player: MotionPlayer | None = None, nodes: int = NODES,
                 settle: float = 0.0, source: tuple | None = None):
        self.hub, self.scene, self.player, self.nodes = hub, scene, player, nodes
        # by mesh id, (the mesh as loaded, its name): stood on another axis by `set_up`
        self.sources: dict[int, tuple] = {} if source is None else {scene.meshes.first.id: source}
        self.settle = settle  # s for the bus to carry the sample's subscription before it plays
        self.jobs = Jobs()
        self.takes = Takes()
        self.tasks: list[asyncio.Task] = []

    # --- what viewers see ------------------------------------------------------------------------------
    @property
    def mesh_id(self) -> int:
        return self.scene.meshes.first.id

    def state(self) -> dict:
        return self.scene.state()

    def transforms_blocks(self) -> list[bytes]:
        return self.scene.transforms_blocks()

    async def mesh_json(self, mesh_id: int) -> bytes | None:
        m = self.scene.meshes.get(mesh_id)
        if m is None:
            return None
        return json.dumps(mesh_payload(m.mesh, m.graph, m.id, m.name)).encode()

    # --- what people do --------------------------------------------------------------------------------
    async def command(self, client: str, msg: dict, raw: bytes) -> None:
        kind, scene = msg["type"], self.scene
        client = person_client(client, parse_person(msg))  # one of several people in the page's camera
        mesh = parse_mesh(msg)
        if kind == "possess":
            scene.scene_mesh(mesh)  # an unknown mesh is refused before the sample stops
            if self.player is not None and client != SAMPLE_CLIENT:
                await self.stop_sample()  # a live user takes over from the sample motion
            await scene.possess(client, check_subset(msg.get("subset")), check_hand(msg.get("hand")), mesh)
        elif kind == "release":
            await scene.release(client)
        elif kind == "subset":
            await scene.set_subset(client, check_subset(msg.get("subset")))
        elif kind == "place":
            scene.place(*parse_place(msg), mesh)
        elif kind == "fit":
            scene.fit(client, mesh)
        elif kind == "player":
            await (self.start_sample() if msg.get("on") else self.stop_sample())
        else:
            raise ProtocolError(f"unknown message type {kind!r}")

    def forget(self, client: str) -> None:
        for user in [u for u in self.scene.users if u == client or is_person_of(u, client)]:
            self.scene.forget(user)

    def set_joint_map(self, joint_map) -> dict | None:
        self.scene.joint_map = joint_map
        self.scene.publish_state()
        return self.scene.state()["joint_map"]

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

    async def play_motion(self, name: str, data: bytes) -> dict:
        """Play an uploaded motion file (`player.PLAYABLE`) as the sample motion, in a loop, possessing the
        mesh as the sample does; BadMotionError for a file that does not read or is no humanoid."""
        frames, fps = await asyncio.to_thread(read_motion, name, data)
        if self.player is None:
            self.player = MotionPlayer(self.hub, frames, fps, SAMPLE_CLIENT, playing=False)
            self.tasks.append(asyncio.get_running_loop().create_task(self.player.run()))
        else:
            await self.stop_sample()
            self.player.frames, self.player.fps = frames, fps
        await self.start_sample()
        return {"motion": Path(name).name, "frames": len(frames), "fps": fps}

    # --- meshes ---------------------------------------------------------------------------------------
    def _mesh_ready(self, job: Job, mesh, graph, name: str, upright, raw, replace: int | None) -> None:
        """In the event loop: a prepared mesh replaces mesh `replace` or, with None, joins the scene."""
        if self.player is not None:
            self.player.playing = False
        if replace is None:
            job.mesh_id = self.scene.add_mesh(mesh, graph, name, upright)
        else:
            self.sources.pop(replace, None)
            job.mesh_id = self.scene.replace_mesh(replace, mesh, graph, name, upright)
        self.sources[job.mesh_id] = (raw, name)

    def start_job(self, name: str, data: bytes, scan_options: dict | None = None, add: bool = False) -> Job:
        """Prepare an uploaded mesh in a worker thread; when ready it replaces the first mesh, or with `add`
        joins the scene beside the others."""
        job = self.jobs.new(name)
        replace = None if add else self.mesh_id

        def ready(mesh, graph, mesh_name: str, upright, raw) -> None:
            target = replace if replace in self.scene.meshes else (None if add else self.mesh_id)
            self._mesh_ready(job, mesh, graph, mesh_name, upright, raw, target)

        prepare_upload(job, data, self.nodes, asyncio.get_running_loop(), ready, scan_options)
        return job

    def set_up(self, up: str, mesh_id: int | None = None) -> Job:
        if up not in AXES:
            raise KinetreError(f"up must be one of {', '.join(AXES)}, got {up!r}")
        target = self.scene.scene_mesh(mesh_id).id
        if target not in self.sources:
            raise KinetreError("the mesh as loaded is not kept here: load it again to stand it on another axis")
        raw, name = self.sources[target]
        job = self.jobs.new(name)
        loop = asyncio.get_running_loop()

        def work() -> None:
            try:
                mesh, graph, upright = prepare_upright(raw, name, self.nodes, up=up)
            except Exception as exc:  # a bug must still reach the page as a message, not a dead job
                job.failed(f"{name}: could not stand the mesh up ({type(exc).__name__}: {exc})")
                return

            def swap() -> None:
                if target not in self.scene.meshes:
                    job.failed(f"{name}: the mesh was removed or replaced meanwhile")
                    return
                self._mesh_ready(job, mesh, graph, name, upright, raw, target)
                job.stage, job.fraction, job.done = "ready", 1.0, True

            loop.call_soon_threadsafe(swap)

        threading.Thread(target=work, daemon=True).start()
        return job

    async def remove_mesh(self, mesh_id: int) -> None:
        self.scene.remove_mesh(mesh_id)
        self.sources.pop(mesh_id, None)

    # --- takes -----------------------------------------------------------------------------------------
    def start_recording(self) -> None:
        self.scene.start_recording()

    async def stop_recording(self) -> dict:
        return await record_take(self.scene, self.takes)

    # --- lifetime --------------------------------------------------------------------------------------
    async def start(self) -> None:
        """Start the solver, the scene's loop and the sample motion (which possesses the mesh)."""
        loop = asyncio.get_running_loop()
        await self.scene.start()
        self.tasks.append(loop.create_task(self.scene.run()))
        if self.player is not None:
            self.tasks.append(loop.create_task(self.player.run()))
            await asyncio.sleep(self.settle)
            await self.start_sample()

    async def close(self) -> None:
        for task in self.tasks:
            task.cancel()
        self.scene.close()
        self.takes.close()
