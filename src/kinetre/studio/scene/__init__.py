"""The server-side scene: meshes, graphs, rigs and solvers (the render component, minus the rendering).

Its modules follow a frame's path through it:

    users        frames in: each user's newest frame (latest wins)
    meshes       the meshes, each with its graph, placement, rig and solver; place and fit
    possession   who possesses which mesh; each mesh's rig
    solve_loop   each mesh's solves (its solver: solve_worker) and the one place a pose goes out
    takes        each mesh's solved frames, recorded to a take log
    state        the state message every page shows

`Scene` ties them together for the server (host.py): it subscribes to every skeleton subject (SKELETONS),
solves each mesh as its possessors' frames come in, and publishes each mesh's node matrices on its transforms
subject.
"""
from __future__ import annotations

import asyncio
import json
import logging
from pathlib import Path
from typing import Callable

from ...deform.pose import GraphPose
from ...graph.graph import DeformationGraph
from ...mesh.mesh import Mesh
from ...mesh.upright import Upright
from ...skeleton.subsets import subset_mask
from ..channels import Channels, Frame, now_ms
from ..placement import beside
from ..subjects import SKELETONS, STATE
from . import meshes as placing
from .meshes import MeshError, Meshes, SceneMesh
from .possession import Possession
from .solve_loop import LATE_S, Publisher, SolveLoops
from .solve_worker import InlineSolver
from .state import scene_state
from .takes import Recording, TakeFrame, resample
from .users import User, Users

__all__ = ["Scene", "SceneMesh", "MeshError", "TakeFrame", "resample", "User", "LATE_S"]

log = logging.getLogger("kinetre.studio")


class Scene:
    """Meshes + graphs + rigs + solvers, driven by skeleton channels.

    Each mesh has its own graph, placement, rig and solver; each user possesses at most one mesh, and every
    mesh is solved from the users possessing it. Commands that name no mesh apply to the first.

    Parameters
    ----------
    hub : Channels
    mesh : Mesh
        In metres, standing on y = 0 (see `placement.standing_mesh`).
    graph : DeformationGraph
        Built on `mesh`.
    name : str
        Shown in the page.
    solver : InlineSolver or SolveWorker, optional
        The first mesh's solver (default: an InlineSolver).
    new_solver : callable, optional
        Makes the solver of each mesh added later (default: InlineSolver).
    clean : bool
        Clean camera users' body frames live before the solve: smoothed, feet held on one floor for the room
        (kinetre.motion.cleanup; on by default, off with `kinetre studio --raw`).
    contact : bool
        Also hold the feet of mocap users (the sample player, VMC performers), unsmoothed (`--contact`).
    """

    def __init__(self, hub: Channels, mesh: Mesh, graph: DeformationGraph, name: str = "mesh", solver=None,
                 upright: Upright | None = None, new_solver: Callable[[], object] = InlineSolver,
                 clean: bool = True, contact: bool = False):
        self.hub = hub
        self.new_solver = new_solver
        self.meshes = Meshes()
        self.users = Users(clean, contact)
        self.recording = Recording()
        self.publisher = Publisher(hub, self.recording)
        self.possession = Possession(self.users, self.meshes, self.publisher, lambda m: self.solves.kick(m))
        self.solves = SolveLoops(self.users, self.meshes, self.publisher, self.possession.rebuild)
        self.joint_map = None  # a JointMap: the n-th user to possess a mesh drives with the joints sources[n] keeps
        self._state_seq = 0
        self._skeletons = None  # the subscription, whose `skipped` counts frames merged latest-wins
        first = SceneMesh(self.meshes.next_id(), mesh, graph, name,
                          solver if solver is not None else InlineSolver(), upright)
        self.meshes[first.id] = first
        self.publisher.publish(first, now_ms())
        self.publish_state()

    @property
    def last_error(self) -> str:
        return self.solves.last_error

    def scene_mesh(self, mesh_id: int | None = None) -> SceneMesh:
        """The mesh `mesh_id` (None: the first); MeshError (404) naming the meshes held otherwise."""
        return self.meshes.named(mesh_id)

    # --- meshes and placement -------------------------------------------------------------------------
    def replace_mesh(self, mesh_id: int, mesh: Mesh, graph: DeformationGraph, name: str,
                     upright: Upright | None = None) -> int:
        """Swap in a new mesh for mesh `mesh_id`, in its place and where it stands: its possessors are
        released and its pose is at rest; it gets a new id (pages load it anew), which is returned.
        `upright`: the up axis it was stood on (shown on the page, which can override it)."""
        old = self.meshes.named(mesh_id)
        self.recording.drop(old.id)
        self.possession.release_all(old)
        new = SceneMesh(self.meshes.next_id(), mesh, graph, name, old.solver, upright, old.placement)
        self.meshes.replace(old, new)
        self.recording.add(new.id)  # the take goes on with the new mesh
        self.solves.retire(old)
        self.solves.start(new)
        self.publisher.publish(new, now_ms())
        self.publish_state()
        return new.id

    def add_mesh(self, mesh: Mesh, graph: DeformationGraph, name: str, upright: Upright | None = None) -> int:
        """Add a mesh beside the others (see `placement.beside`), at rest, with a solver of its own; its id."""
        boxes = [m.box() for m in self.meshes.values()]
        new = SceneMesh(self.meshes.next_id(), mesh, graph, name, self.new_solver(), upright,
                        beside(boxes, mesh, self.meshes.first.placement))
        self.meshes[new.id] = new
        self.recording.add(new.id)
        self.solves.start(new)
        self.publisher.publish(new, now_ms())
        self.publish_state()
        return new.id

    def remove_mesh(self, mesh_id: int) -> None:
        """Remove mesh `mesh_id`, releasing its possessors. The scene keeps at least one mesh, and none is
        removed while a take records (its frames would be lost)."""
        m = self.meshes.named(mesh_id)
        if len(self.meshes) == 1:
            raise MeshError(f"mesh {mesh_id} is the scene's only mesh: load another one to replace it instead")
        if self.recording.on:
            raise MeshError(f"mesh {mesh_id} is being recorded: stop the take before removing it")
        self.possession.release_all(m)
        del self.meshes[mesh_id]
        self.solves.retire(m)
        self.publish_state()

    def place(self, scale: float, position, yaw: float, mesh_id: int | None = None) -> None:
        placing.place(self.meshes.named(mesh_id), scale, position, yaw)
        self.publish_state()

    def fit(self, client: str, mesh_id: int | None = None) -> None:
        """Scale the mesh to the user's height and stand it where the user stands (paper: scale to height).
        Without `mesh_id`: the mesh the user possesses, else the first."""
        user = self.users.get(client)
        if mesh_id is None and user is not None and user.mesh is not None:
            mesh_id = user.mesh
        placing.fit(self.meshes.named(mesh_id), user)
        self.publish_state()

    # --- users --------------------------------------------------------------------------------------
    def forget(self, client: str) -> None:
        """A client disconnected: it lets go and disappears."""
        user = self.users.pop(client, None)
        if user is None:
            return
        if user.bind is not None:
            m = self.meshes.get(user.mesh)
            user.let_go()
            if m is not None:
                self.possession.rebuild_later(m)
        self.publish_state()

    def receive(self, frame: Frame) -> None:
        """A skeleton frame from the hub (already validated by the server that published it)."""
        user = self.users.receive(frame)
        m = self.meshes.get(user.mesh) if user is not None and user.bind is not None else None
        if m is not None:
            self.solves.wake(m)

    async def possess(self, client: str, subset=None, hand: str | None = None, mesh_id: int | None = None) -> None:
        """User `client` possesses mesh `mesh_id` (None: the first); see `Possession.possess`. MeshError for
        an unknown mesh."""
        m = self.meshes.named(mesh_id)
        await self.possession.possess(self.users.user(client), m, subset, hand, self.joint_map)
        self.publish_state()

    async def release(self, client: str) -> None:
        user = self.users.get(client)
        if user is None or user.bind is None:
            return
        await self.possession.release(user)
        self.publish_state()

    async def set_subset(self, client: str, subset) -> None:
        """Change which joints drive; a possessing user re-binds with the new subset at the current pose."""
        user = self.users.user(client)
        if user.latest is not None and subset is not None and user.hand is None:
            subset_mask(user.latest.model, subset)  # BadSkeletonError on an unknown name
        if user.bind is not None:
            await self.possess(client, subset, user.hand, user.mesh)
            return
        user.subset = subset
        self.publish_state()

    # --- the solve loops ----------------------------------------------------------------------------
    async def run(self) -> None:
        """Consume skeleton frames and publish transforms until cancelled (see `SolveLoops`)."""
        sub = self._skeletons = self.hub.subscribe(SKELETONS)
        # each frame is taken in the publisher's own call (the server's handler, or the bus callback): a
        # hop through a task would make it wait a loop iteration, behind whatever else is ready
        sub.direct = self._take
        loop = asyncio.get_running_loop()
        helpers = [loop.create_task(self._feed(sub)), loop.create_task(self._heartbeat())]
        self.solves.running = True
        for m in self.meshes.values():
            self.solves.start(m)
        try:
            await loop.create_future()  # until cancelled
        finally:
            self.solves.stop_all()
            for task in helpers:
                task.cancel()
            sub.close()

    async def _heartbeat(self, period: float = 1.0) -> None:
        """Re-publish the state when users came or frame counts moved (pages show who is connected)."""
        last = None
        while True:
            await asyncio.sleep(period)
            now = [(u.client, u.frames) for u in self.users.values()]
            if now != last:
                self.publish_state()
                last = now

    async def _feed(self, sub) -> None:
        while True:
            frame = await sub.next()
            if frame is None:
                return
            self._take(frame)

    def _take(self, frame: Frame) -> bool:
        self.users.frames_in += 1
        try:
            self.receive(frame)
        except Exception:
            log.exception("bad frame on %s", frame.subject)
        return True

    async def solve_once(self, late: float | None = None, mesh_id: int | None = None) -> GraphPose | None:
        """Solve mesh `mesh_id` (None: the first) with its possessing users' newest frames and publish its
        node matrices (see `SolveLoops.solve`)."""
        return await self.solves.solve(self.meshes.named(mesh_id), late)

    def transforms_blocks(self) -> list[bytes]:
        """Every mesh's current pose, the first mesh's first."""
        return [self.publisher.block(m) for m in self.meshes.values()]

    def publish_rest(self) -> None:
        """Publish again the pose of each mesh nobody possesses (a remote scene's heartbeat: gateways that
        joined late get every mesh's pose)."""
        for m in self.meshes.values():
            if m.rig is None:
                self.publisher.republish(m)

    async def start(self) -> None:
        """Start every mesh's solver (a worker process spawns)."""
        for m in self.meshes.values():
            await m.solver.start()

    def close(self) -> None:
        """Stop every mesh's solver."""
        for m in self.meshes.values():
            m.solver.close()

    # --- state for the pages ------------------------------------------------------------------------
    def state(self) -> dict:
        return scene_state(self.meshes, self.users, self.recording.on, self.joint_map, self.last_error,
                           self._skeletons.skipped if self._skeletons else 0)

    def publish_state(self) -> None:
        self._state_seq += 1
        self.hub.publish(Frame(STATE, self._state_seq, now_ms(), json.dumps(self.state()).encode()))

    # --- takes --------------------------------------------------------------------------------------
    def start_recording(self, folder: str | Path | None = None) -> Path:
        """Record every mesh's solved frames to a take log each in `folder` (a temporary folder by default),
        flushed per frame; returns the folder."""
        folder = self.recording.start(list(self.meshes), folder)
        self.publish_state()
        return folder

    def stop_recordings(self) -> dict[int, list[TakeFrame]]:
        """Each mesh's recorded frames by mesh id (the first mesh's first), read back from the take logs
        (which are then removed)."""
        takes = self.recording.stop()
        self.publish_state()
        return {i: takes[i] for i in self.meshes if i in takes}
