"""The server-side scene: meshes, graphs, rigs and solvers (the render component, minus the rendering).

It subscribes to every skeleton subject (SKELETONS) and keeps each user's newest frame. It holds one or more
meshes side by side, each with its own graph, placement, rig and solver; each user possesses at most one of
them. While anyone possesses a mesh, the mesh's graph pose is solved from all its possessing users at once
(their constraints add up in one energy) and its node matrices are published (the default mesh's on
TRANSFORMS, every other one's on `transforms_subject(id)`). Frames that arrive while a solve runs are merged
latest-wins, so a slow solve lowers the frame rate instead of building a queue.
"""
from __future__ import annotations

import asyncio
import itertools
import json
import logging
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..deform.pose import GraphPose
from ..errors import AttachError, KinetreError
from ..graph.graph import DeformationGraph
from ..mesh.mesh import Mesh
from ..mesh.upright import Upright
from ..skeleton.models import HAND21, Skeleton
from ..motion.fit import yaw_rotation
from ..motion.hands import SIDES, HandPuppet, fit_puppet
from ..skeleton.rig import BONE_RADIUS, REACH
from ..skeleton.subsets import subset_mask
from ..wire.transforms import pack_transforms
from .channels import Channels, Frame, now_ms
from .placement import Placement, beside
from .protocol import ProtocolError, SkeletonFrame, parse_frame, parse_message
from .solve_worker import InlineSolver, SolverLost
from .subjects import SKELETONS, STATE, TRANSFORMS, last_token, transforms_subject
from .takelog import TakeLog, read_take_log

log = logging.getLogger("kinetre.studio")

GATHER_S = 0.010  # longest wait for another possessing user's frame that is due (see Scene._gather)
GATHER_SLACK_S = 0.005  # how late a user's frame may be (arrival jitter) and still be waited for
LATE_S = 0.015  # a frame this long in the scene yields after its solve's next step (see Scene.solve_once)
# how long a possession waits for the user's first tracked frame: a page sends "possess" right after its
# first detection, and on a busy host that frame may still be on its way through the hub
FIRST_FRAME_S = 3.0


async def arrival(ready: Callable[[], bool], wait: float = FIRST_FRAME_S) -> None:
    """Return once `ready()` holds or `wait` seconds have passed (the caller then checks it again)."""
    deadline = time.monotonic() + wait
    while not ready() and time.monotonic() < deadline:
        await asyncio.sleep(0.05)


@dataclass
class User:
    """One capture source (a page's webcam, or the sample-motion player)."""

    client: str
    parsed: Skeleton | None = None  # world frame, newest parsed (see `latest`)
    parsed_hands: np.ndarray | None = None  # (2, 21, 3) of the newest parsed frame (see `hands`)
    parsed_blendshapes: np.ndarray | None = None  # (52,) of the newest parsed frame (see `blendshapes`)
    raw: bytes | None = None  # a newer frame not parsed yet (a user who does not drive the solve)
    seq: int = -1
    t: float = 0.0
    frames: int = 0
    used: int = -1  # seq of the frame the last solve used
    arrived: float = 0.0  # monotonic time the newest frame arrived (s)
    period: float = 0.0  # running mean of the time between its frames (s)
    bind: Skeleton | None = None  # mesh frame, the pose at possession (None = not possessing)
    mesh: int | None = None  # the id of the mesh it possesses
    subset: str | list | None = None
    stand: tuple | None = None  # (R, t): where a joint map's source stands, x -> R x + t (see Scene.stand_in)
    hand: str | None = None  # "left" or "right" while a hand possesses (a hand puppet), None for the body
    puppet: HandPuppet | None = None  # that hand put inside the mesh, fitted at possession

    @property
    def latest(self) -> Skeleton | None:
        """The newest frame (world frame). Parsed on first use: of the many users sending frames only the
        possessing ones drive the solve; the others' frames are needed only when one fits or possesses. A
        frame that does not parse leaves the last good one (it came through a server that validated it, so
        only a foreign publisher in the room can send one)."""
        self._parse_raw()
        return self.parsed

    @property
    def hands(self) -> np.ndarray | None:
        """(2, 21, 3) the left and right hand landmarks of the newest frame (world frame, metres, +Y up, the
        wrist at the skeleton's wrist; NaN rows for a hand not seen), or None when the user sends no hands."""
        self._parse_raw()
        return self.parsed_hands

    def seen_hand(self, side: str) -> np.ndarray | None:
        """(21, 3) hand `side` ("left", "right") of the newest frame, or None when it is not seen there."""
        marks = self.hands
        if marks is None or not np.isfinite(marks[SIDES.index(side)]).all():
            return None
        return marks[SIDES.index(side)]

    @property
    def tracking(self) -> bool:
        """Whether the newest frame tracks any joint."""
        return self.latest is not None and bool(self.latest.tracked.any())

    @property
    def blendshapes(self) -> np.ndarray | None:
        """(52,) the face blendshape weights of the newest frame (`skeleton.mediapipe.BLENDSHAPES` order), or
        None without a face."""
        self._parse_raw()
        return self.parsed_blendshapes

    def take_frame(self, frame: SkeletonFrame) -> None:
        """Keep `frame` as the newest parsed frame."""
        self.parsed, self.parsed_hands, self.parsed_blendshapes, self.raw = \
            frame.skeleton, frame.hands, frame.blendshapes, None

    def _parse_raw(self) -> None:
        if self.raw is not None:
            raw, self.raw = self.raw, None
            try:
                self.take_frame(parse_frame(parse_message(raw)))
            except ProtocolError:
                pass

    def placed(self, skeleton: Skeleton) -> Skeleton:
        """The frame moved to where the user's joint-map source stands (unchanged without one)."""
        return skeleton if self.stand is None else skeleton.transformed(1.0, *self.stand)

    def hand_frame(self) -> Skeleton:
        """The newest frame of the possessing hand as a `HAND21` skeleton (world frame; untracked when the
        hand is not seen)."""
        marks = self.hands
        side = np.full((21, 3), np.nan) if marks is None else marks[SIDES.index(self.hand)]
        return Skeleton.from_positions(HAND21, side)

    def driving(self, placement: Placement) -> Skeleton:
        """The frame that drives the mesh, in its own frame: the possessing hand put inside it, or the body
        where the mesh stands in the room (`placement`), moved to its joint-map source's place, masked."""
        if self.hand is not None:
            return self.masked(self.puppet.place(self.hand_frame()))
        return self.masked(placement.to_local(self.placed(self.latest)))

    def masked(self, skeleton: Skeleton) -> Skeleton:
        """Joints outside the user's subset count as untracked, so they neither attach nor pull."""
        if self.subset is None:
            return skeleton
        return Skeleton(skeleton.model, skeleton.positions, skeleton.tracked & subset_mask(skeleton.model,
                                                                                           self.subset))


@dataclass
class TakeFrame:
    """One solved frame of a take: the pose and, per possessing user, the skeleton, hands and blendshapes it
    was solved from (hands and blendshapes only for users who sent them)."""

    t: float
    pose: GraphPose
    skeletons: dict[str, Skeleton] = field(default_factory=dict)
    hands: dict[str, np.ndarray] = field(default_factory=dict)
    blendshapes: dict[str, np.ndarray] = field(default_factory=dict)


class MeshError(KinetreError):
    """A command naming a mesh the scene does not hold (`status` 404), or a mesh that cannot be removed now
    (400)."""

    def __init__(self, message: str, status: int = 400):
        super().__init__(message)
        self.status = status


@dataclass(eq=False)
class SceneMesh:
    """One mesh of the scene: its graph, where it stands, and the rig and solver its possessors drive."""

    id: int
    mesh: Mesh
    graph: DeformationGraph
    name: str
    solver: object
    upright: Upright | None = None
    placement: Placement = field(default_factory=Placement)
    rig: object = None  # the solver holding the rig while anyone possesses this mesh
    possessors: list[str] = field(default_factory=list)  # order of the skeletons given to the rig
    attached: list = field(default_factory=list)  # per possessor, the joints that attached
    pose: GraphPose | None = None
    seq: int = 0  # transform blocks published (per mesh: each mesh's blocks go on a subject of their own)
    recording: TakeLog | None = None
    solve_ms: list[float] = field(default_factory=list)  # recent solve round trips (wall), for the state line
    solve_cpu_ms: list[float] = field(default_factory=list)  # the last 600 solves' CPU time in the solver
    stopped: int = 0  # solves that yielded to a newer frame after a step (solve_worker.yielding)
    # (pose, t_source, skeletons, hands, blendshapes) solved, published once the next solve is sent
    unpublished: tuple | None = None
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)  # one attach/solve at a time
    dirty: asyncio.Event = field(default_factory=asyncio.Event)  # a possessor's frame waits for a solve

    def __post_init__(self):
        if self.pose is None:
            self.pose = GraphPose.identity(self.graph.node_count)

    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """World-space (min, max) of the mesh at rest, as placed."""
        p = self.placement
        world = p.scale * self.mesh.vertices @ p.rotation.T + np.asarray(p.position)
        return world.min(axis=0), world.max(axis=0)


class Scene:
    """Meshes + graphs + rigs + solvers, driven by skeleton channels.

    Each mesh has its own graph, placement, rig and solver; each user possesses at most one mesh, and every
    mesh is solved from the users possessing it. The first mesh is the default: commands that name no mesh
    apply to it, and its transform blocks go on TRANSFORMS (each other mesh's on `transforms_subject(id)`).

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
    """

    def __init__(self, hub: Channels, mesh: Mesh, graph: DeformationGraph, name: str = "mesh", solver=None,
                 upright: Upright | None = None, new_solver: Callable[[], object] = InlineSolver):
        self.hub = hub
        self.new_solver = new_solver
        self.meshes: dict[int, SceneMesh] = {}  # in the order they were added: the first is the default
        self.users: dict[str, User] = {}
        self.last_error = ""
        self.joint_map = None  # a JointMap: the n-th user to possess a mesh drives with the joints sources[n] keeps
        self._ids = itertools.count(1)
        self._state_seq = 0
        self._loops: dict[int, asyncio.Task] = {}  # each mesh's solve loop, while `run` runs
        self._running = False
        self._recording_dir: Path | None = None
        self.late = 0  # skeleton frames older than the user's newest (dropped)
        self.superseded = 0  # possessing users' frames replaced by a newer one before any solve used them
        self.frames_in = 0  # skeleton frames that reached the scene
        self._skeletons = None  # the subscription, whose `skipped` counts frames merged latest-wins
        first = SceneMesh(next(self._ids), mesh, graph, name, solver if solver is not None else InlineSolver(),
                          upright)
        self.meshes[first.id] = first
        self._publish_pose(first, now_ms())
        self.publish_state()

    # --- the default mesh, as a scene of one mesh had it ----------------------------------------------------
    @property
    def default(self) -> SceneMesh:
        return next(iter(self.meshes.values()))

    mesh = property(lambda self: self.default.mesh)
    graph = property(lambda self: self.default.graph)
    name = property(lambda self: self.default.name)
    upright = property(lambda self: self.default.upright)
    mesh_id = property(lambda self: self.default.id)
    solver = property(lambda self: self.default.solver)
    rig = property(lambda self: self.default.rig)
    possessors = property(lambda self: self.default.possessors)
    attached = property(lambda self: self.default.attached)
    pose = property(lambda self: self.default.pose)
    seq = property(lambda self: self.default.seq)
    recording = property(lambda self: self.default.recording)
    solve_ms = property(lambda self: self.default.solve_ms)
    _unpublished = property(lambda self: self.default.unpublished)

    @property
    def placement(self) -> Placement:
        return self.default.placement

    def scene_mesh(self, mesh_id: int | None = None) -> SceneMesh:
        """The mesh `mesh_id` (None: the default); MeshError (404) naming the meshes held otherwise."""
        if mesh_id is None:
            return self.default
        m = self.meshes.get(mesh_id)
        if m is None:
            raise MeshError(f"no mesh {mesh_id} in the scene (its meshes: "
                            f"{', '.join(str(i) for i in self.meshes)})", 404)
        return m

    # --- meshes and placement -------------------------------------------------------------------------
    def set_mesh(self, mesh: Mesh, graph: DeformationGraph, name: str, upright: Upright | None = None) -> int:
        """Swap in a new mesh for the default one (see `replace_mesh`); returns its id."""
        return self.replace_mesh(self.default.id, mesh, graph, name, upright)

    def replace_mesh(self, mesh_id: int, mesh: Mesh, graph: DeformationGraph, name: str,
                     upright: Upright | None = None) -> int:
        """Swap in a new mesh for mesh `mesh_id`, in its place and where it stands: its possessors are
        released and its pose is at rest; it gets a new id (pages load it anew), which is returned.
        `upright`: the up axis it was stood on (shown on the page, which can override it)."""
        old = self.scene_mesh(mesh_id)
        self._flush(old)
        if old.recording is not None:
            old.recording.close()
        self._release_all(old)
        new = SceneMesh(next(self._ids), mesh, graph, name, old.solver, upright, old.placement)
        self.meshes = {(new.id if i == old.id else i): (new if i == old.id else m) for i, m in self.meshes.items()}
        if self._recording_dir is not None:  # the take goes on with the new mesh
            new.recording = TakeLog(self._log_path(new))
        self._retire(old)
        self._start_loop(new)
        self._publish_pose(new, now_ms())
        self.publish_state()
        return new.id

    def add_mesh(self, mesh: Mesh, graph: DeformationGraph, name: str, upright: Upright | None = None) -> int:
        """Add a mesh beside the others (see `placement.beside`), at rest, with a solver of its own; its id."""
        boxes = [m.box() for m in self.meshes.values()]
        new = SceneMesh(next(self._ids), mesh, graph, name, self.new_solver(), upright,
                        beside(boxes, mesh, self.default.placement))
        self.meshes[new.id] = new
        if self._recording_dir is not None:
            new.recording = TakeLog(self._log_path(new))
        self._start_loop(new)
        self._publish_pose(new, now_ms())
        self.publish_state()
        return new.id

    def remove_mesh(self, mesh_id: int) -> None:
        """Remove mesh `mesh_id`, releasing its possessors. The scene keeps at least one mesh, and none is
        removed while a take records (its frames would be lost)."""
        m = self.scene_mesh(mesh_id)
        if len(self.meshes) == 1:
            raise MeshError(f"mesh {mesh_id} is the scene's only mesh: load another one to replace it instead")
        if self._recording_dir is not None:
            raise MeshError(f"mesh {mesh_id} is being recorded: stop the take before removing it")
        self._release_all(m)
        del self.meshes[mesh_id]
        self._retire(m)
        self._publish_pose(self.default, now_ms())  # the default may have changed: its blocks on TRANSFORMS
        self.publish_state()

    def _release_all(self, m: SceneMesh) -> None:
        for user in self.users.values():
            if user.mesh == m.id:
                user.bind = user.mesh = user.stand = user.hand = user.puppet = None
        m.rig, m.possessors, m.unpublished = None, [], None

    def place(self, scale: float, position, yaw: float, mesh_id: int | None = None) -> None:
        m = self.scene_mesh(mesh_id)
        if not (np.isfinite(scale) and scale > 0):
            raise ProtocolError(f"scale must be a positive number, got {scale}")
        pos = tuple(float(v) for v in position)
        if len(pos) != 3 or not np.all(np.isfinite(pos)) or not np.isfinite(yaw):
            raise ProtocolError("position must be 3 finite numbers and yaw a finite number")
        m.placement = Placement(float(scale), pos, float(yaw))
        self.publish_state()

    def fit(self, client: str, mesh_id: int | None = None) -> None:
        """Scale the mesh to the user's height and stand it where the user stands (paper: scale to height).
        Without `mesh_id`: the mesh the user possesses, else the default."""
        user = self.users.get(client)
        if mesh_id is None and user is not None and user.mesh is not None:
            mesh_id = user.mesh
        m = self.scene_mesh(mesh_id)
        if user is None or user.latest is None or user.latest.tracked.sum() < 2:
            raise AttachError("no tracked skeleton yet: step in front of the camera first")
        sk = user.latest
        height = sk.height
        mesh_height = float(np.ptp(m.mesh.vertices[:, 1]))
        if height <= 0.3 or mesh_height <= 0:
            raise AttachError(f"the tracked skeleton is {height:.2f} m tall: show your whole body to the camera")
        m.placement = Placement.fitted(sk, m.mesh, m.placement.yaw)
        self.publish_state()

    # --- users --------------------------------------------------------------------------------------
    def user(self, client: str) -> User:
        if client not in self.users:
            self.users[client] = User(client)
        return self.users[client]

    def hands(self, client: str) -> np.ndarray | None:
        """User `client`'s newest hands, (2, 21, 3) left and right in the studio's world frame (NaN rows where a
        hand is not seen), or None for a user who sends none (see `User.hands`)."""
        user = self.users.get(client)
        return None if user is None else user.hands

    def blendshapes(self, client: str) -> np.ndarray | None:
        """User `client`'s newest face blendshapes (52,), or None (see `User.blendshapes`)."""
        user = self.users.get(client)
        return None if user is None else user.blendshapes

    def forget(self, client: str) -> None:
        """A client disconnected: it lets go and disappears."""
        if client in self.users:
            user = self.users[client]
            if user.bind is not None:
                m = self.meshes.get(user.mesh)
                user.bind, user.mesh = None, None
                if m is not None:
                    self._rebuild_rig_later(m)
            del self.users[client]
            self.publish_state()

    def receive(self, frame: Frame) -> None:
        """A skeleton frame from the hub (already validated by the server that published it)."""
        client = last_token(frame.subject)
        user = self.user(client)
        parsed = None
        if frame.value is not None:
            parsed = frame.value  # decoded by the publisher in this process
        elif user.bind is not None:
            try:
                parsed = parse_frame(parse_message(frame.data))
            except ProtocolError:
                return
        # without a parsed frame, the bus envelope's seq and t; the JSON is parsed when needed (User.latest)
        seq, t = (frame.seq, frame.t) if parsed is None else (parsed.seq, parsed.t)
        if seq <= user.seq and user.frames:
            self.late += 1
            return  # late or duplicate frame: skip, never reorder
        if user.bind is not None and user.frames and user.used != user.seq:
            self.superseded += 1  # merged latest-wins: the solve only ever takes the newest
        if parsed is None:
            user.raw = frame.data
        else:
            user.take_frame(parsed)
        user.seq, user.t = seq, t
        user.frames += 1
        arrived = time.monotonic()
        if user.arrived:
            gap = min(arrived - user.arrived, 1.0)
            user.period = gap if not user.period else user.period + 0.1 * (gap - user.period)
        user.arrived = arrived
        m = self.meshes.get(user.mesh) if user.bind is not None else None
        if m is not None:
            m.dirty.set()
            m.solver.newer_frame()  # a running solve yields to this frame (solve_worker.yielding)

    async def possess(self, client: str, subset=None, hand: str | None = None, mesh_id: int | None = None) -> None:
        """Bind the user's current pose to mesh `mesh_id` (None: the default), or with `hand` ("left",
        "right") that hand's, fitted into the mesh from the shapes (a hand puppet), letting go of any other
        mesh it possessed; raises AttachError when nothing is near the mesh or the hand is not seen,
        MeshError for an unknown mesh."""
        m = self.scene_mesh(mesh_id)
        user = self.user(client)
        if hand is not None:
            check_hand(hand)
            await arrival(lambda: user.seen_hand(hand) is not None)
            await self._possess_by_hand(user, subset, hand, m)
            return
        await arrival(lambda: user.tracking)
        if not user.tracking:
            raise AttachError("no tracked skeleton from this client yet: nothing to possess with")
        source = None
        if subset is None and self.joint_map is not None:
            others = sum(1 for c, u in self.users.items() if c != client and u.bind is not None and u.mesh == m.id)
            if others < len(self.joint_map.sources):
                source = self.joint_map.sources[others]
                subset = source.joint_names(user.latest.model, self.joint_map.path)
        if subset is not None:
            subset_mask(user.latest.model, subset)  # BadSkeletonError on an unknown name
        stand = self.stand_in(user.latest, source, m.placement) if source is not None else None
        await self._bind(user, m, subset, None, None, stand)

    async def _possess_by_hand(self, user: User, subset, hand: str, m: SceneMesh) -> None:
        marks = user.seen_hand(hand)
        if marks is None:
            raise AttachError(f"no {hand} hand tracked from this client yet: show it to the camera")
        if subset is not None:
            subset_mask(HAND21, subset)  # BadSkeletonError on a name that is no part of a hand
        frame = Skeleton.from_positions(HAND21, marks)
        # the shape fit searches for a second or so: off the event loop
        fitted = await asyncio.to_thread(fit_puppet, frame, m.mesh, m.graph.nodes)
        await self._bind(user, m, subset, hand, fitted, None)

    async def _bind(self, user: User, m: SceneMesh, subset, hand: str | None, puppet, stand) -> None:
        """Possess mesh `m` with the user's newest frame, driven as given; back to what it was when attaching
        fails. A mesh the user possessed before lets go of it."""
        before = self.meshes.get(user.mesh) if user.bind is not None else None
        old = user.bind, user.subset, user.stand, user.hand, user.puppet, user.mesh
        user.subset, user.stand, user.hand, user.puppet = subset, stand, hand, puppet
        user.bind = user.driving(m.placement)
        user.mesh = m.id
        try:
            await self._rebuild_rig(m)
        except Exception:
            user.bind, user.subset, user.stand, user.hand, user.puppet, user.mesh = old
            await self._rebuild_rig(m)
            raise
        if before is not None and before is not m:
            await self._rebuild_rig(before)
        self.publish_state()

    def stand_in(self, skeleton: Skeleton, source, placement: Placement | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(R, t) that moves a joint-map source's person, turned by its `yaw`, from where they stand to the
        mesh's centre plus its `offset` (metres, turned with the mesh): two people anywhere in one camera's
        view become the front and back legs of one horse, as two separate captures would in a joint take.
        `placement`: the mesh's (default: the default mesh's)."""
        placement = self.placement if placement is None else placement
        root = skeleton.positions[0] if skeleton.tracked[0] else skeleton.positions[skeleton.tracked].mean(axis=0)
        root = np.array([root[0], 0.0, root[2]])
        turn = yaw_rotation(source.yaw)
        target = np.asarray(placement.position, dtype=np.float64) + placement.rotation @ source.offset
        target[1] = 0.0  # only across the floor: the person keeps their height
        return turn, target - turn @ root

    async def release(self, client: str) -> None:
        user = self.users.get(client)
        if user is None or user.bind is None:
            return
        m = self.meshes.get(user.mesh)
        user.bind = user.stand = user.hand = user.puppet = user.mesh = None
        if m is not None:
            await self._rebuild_rig(m)
        self.publish_state()

    async def set_subset(self, client: str, subset) -> None:
        """Change which joints drive; a possessing user re-binds with the new subset at the current pose."""
        user = self.user(client)
        if user.latest is not None and subset is not None and user.hand is None:
            subset_mask(user.latest.model, subset)
        if user.bind is not None:
            await self.possess(client, subset, user.hand, user.mesh)
        else:
            user.subset = subset
            self.publish_state()

    def _rebuild_rig_later(self, m: SceneMesh) -> None:
        asyncio.get_running_loop().create_task(self._rebuild_rig(m))

    async def _rebuild_rig(self, m: SceneMesh) -> None:
        async with m.lock:
            if not self._holds(m):
                return  # replaced or removed meanwhile
            possessors = [c for c, u in self.users.items() if u.bind is not None and u.mesh == m.id]
            if not possessors:
                self._flush(m)
                m.rig, m.possessors = None, []
                m.pose = GraphPose.identity(m.graph.node_count)  # let go: back to rest
                self._publish_pose(m, now_ms())
                return
            users = [self.users[c] for c in possessors]
            binds = [u.bind for u in users]
            # a hand puppet reaches as far as its fit scaled it up (people: the attachment's own reach)
            reach = {} if all(u.puppet is None for u in users) else {
                "reach": [REACH * (1.0 if u.puppet is None else u.puppet.metre) for u in users],
                "bone_radius": [BONE_RADIUS * (1.0 if u.puppet is None else u.puppet.metre) for u in users]}
            m.attached = await m.solver.attach(m.graph, binds if len(binds) > 1 else binds[0], **reach)
            m.rig = m.solver
            m.possessors = possessors
        m.dirty.set()

    # --- the solve loops ----------------------------------------------------------------------------
    async def run(self) -> None:
        """Consume skeleton frames and publish transforms until cancelled: one solve loop per mesh."""
        sub = self._skeletons = self.hub.subscribe(SKELETONS)
        # each frame is taken in the publisher's own call (the server's handler, or the bus callback): a
        # hop through a task would make it wait a loop iteration, behind whatever else is ready
        sub.direct = self._take
        loop = asyncio.get_running_loop()
        helpers = [loop.create_task(self._feed(sub)), loop.create_task(self._heartbeat())]
        self._running = True
        for m in self.meshes.values():
            self._start_loop(m)
        try:
            await loop.create_future()  # until cancelled
        finally:
            self._running = False
            for task in [*helpers, *self._loops.values()]:
                task.cancel()
            self._loops.clear()
            sub.close()

    def _start_loop(self, m: SceneMesh) -> None:
        if self._running:
            self._loops[m.id] = asyncio.get_running_loop().create_task(self._solve_loop(m))

    def _retire(self, m: SceneMesh) -> None:
        """A mesh left the scene: its solve loop ends after the solve in flight (cancelling that would leave
        the solver's reply unread), then its solver, unless a mesh in the scene still uses it."""
        if self._loops.pop(m.id, None) is not None:
            m.dirty.set()  # the loop wakes, sees the mesh gone, and ends
        else:
            self._close_solver(m)

    def _close_solver(self, m: SceneMesh) -> None:
        if not any(other.solver is m.solver for other in self.meshes.values()):
            m.solver.close()

    def _holds(self, m: SceneMesh) -> bool:
        return self.meshes.get(m.id) is m

    async def _solve_loop(self, m: SceneMesh) -> None:
        try:
            while self._holds(m):
                await m.dirty.wait()
                if not self._holds(m):
                    break
                await self._gather(m)
                try:
                    await self._solve(m, LATE_S)
                except Exception as exc:  # one bad frame must not stop the scene for everybody
                    self.last_error = f"solve failed: {type(exc).__name__}: {exc}"
                    log.exception("solve failed")
        finally:
            if not self._holds(m):
                self._close_solver(m)

    async def _gather(self, m: SceneMesh) -> None:
        """Before solving, wait (briefly) for the mesh's other possessing users' frames that are due now.

        Every solve takes all possessors' newest frames. When one user's frame arrives and another's is due
        within half a solve (cameras ticking together, or by chance), solving at once would make that frame
        wait for the whole running solve and then its own; waiting for it costs the first frame only the
        gap, and one solve serves both. A user is waited for only while its next frame is expected (from its
        own frame period) within half a recent solve's time (at most `GATHER_S`) of the first new frame's
        arrival, and not once it is overdue (a user who stopped sending delays nothing).
        """
        while True:
            m.dirty.clear()  # the frames in so far go into this solve
            deadline = self._gather_deadline(time.monotonic(), m)
            if deadline is None:
                return
            self._flush(m)  # no solve starts yet: the last pose goes out now
            try:
                await asyncio.wait_for(m.dirty.wait(), deadline - time.monotonic())
            except asyncio.TimeoutError:
                return

    def _gather_deadline(self, now: float, m: SceneMesh | None = None) -> float | None:
        m = self.default if m is None else m
        users = [self.users[c] for c in m.possessors if c in self.users]
        fresh = [u.arrived for u in users if u.used != u.seq]
        if not fresh or len(fresh) == len(users):
            return None
        solve_s = float(np.median(m.solve_ms[-15:])) / 1000 if m.solve_ms else GATHER_S
        # frames a and b arriving g apart, a solve taking S: solving a at once ends b's wait at 2S - g, waiting
        # for b ends both at g + S (and spares a solve): better while g < S / 2
        limit = min(fresh) + min(GATHER_S, solve_s / 2)
        due = [u.arrived + u.period for u in users if u.used == u.seq and u.period]
        if not any(now - GATHER_SLACK_S <= d <= limit for d in due):
            return None
        return limit  # or sooner: every user's new frame wakes the wait

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
        self.frames_in += 1
        try:
            self.receive(frame)
        except Exception:
            log.exception("bad frame on %s", frame.subject)
        return True

    async def solve_once(self, late: float | None = None, mesh_id: int | None = None) -> GraphPose | None:
        """Solve mesh `mesh_id` (None: the default) with its possessing users' newest frames and publish its
        node matrices.

        The solver yields after a Gauss-Newton step (`solve_worker.yielding`) to a newer frame, or once the
        oldest frame it solves has been `late` seconds in the scene (the live loop: `LATE_S`): its pose is published at once and the next
        frame goes on from it, instead of every viewer's picture waiting for the rest of a long solve. When
        a newer frame already waits as a solve ends, its pose is published once the next solve is under
        way: the solver then works while the transforms go out to every page (the embedded studio's
        fan-out, 3-8 ms), instead of waiting for them."""
        return await self._solve(self.scene_mesh(mesh_id), late)

    async def _solve(self, m: SceneMesh, late: float | None) -> GraphPose | None:
        async with m.lock:
            if m.rig is None or not self._holds(m):
                self._flush(m)
                return None
            users = [self.users[c] for c in m.possessors if c in self.users]
            if len(users) != len(m.possessors):
                self._flush(m)
                return None
            frames = [u.driving(m.placement) for u in users]
            arrived = min((u.arrived for u in users if u.used != u.seq), default=time.monotonic())
            for u in users:
                u.used = u.seq
            t_source = max(u.t for u in users)
            start = time.perf_counter()
            loop = asyncio.get_running_loop()
            if m.unpublished is not None:
                loop.call_soon(self._flush, m)  # runs once the solve's request is out
            timer = None if late is None else loop.call_later(max(arrived + late - time.monotonic(), 0.0),
                                                              m.solver.newer_frame)
            try:
                pose = await m.solver.solve(frames if len(frames) > 1 else frames[0])
            except SolverLost:
                m.rig = None  # the worker died: re-attach everybody at their current pose
                self._rebuild_rig_later(m)
                raise
            finally:
                if timer is not None:
                    timer.cancel()
            m.solve_ms[:] = (m.solve_ms + [1000 * (time.perf_counter() - start)])[-60:]
            m.solve_cpu_ms[:] = (m.solve_cpu_ms + [m.solver.cpu_ms])[-600:]
            m.stopped += bool(getattr(m.solver, "stopped", False))
            m.pose = pose
            m.unpublished = (pose, t_source, {u.client: u.latest for u in users},
                             {u.client: u.hands for u in users if u.hands is not None},
                             {u.client: u.blendshapes for u in users if u.blendshapes is not None})
            if not any(u.seq != u.used for u in users):  # else once the next solve is sent
                self._flush(m)
            return pose

    def _flush(self, m: SceneMesh) -> None:
        """Record and publish the mesh's last solved pose if it is not out yet."""
        if m.unpublished is None:
            return
        pose, t_source, skeletons, hands, blendshapes = m.unpublished
        m.unpublished = None
        if m.recording is not None:  # on disk before any viewer sees the frame
            m.recording.append(m.seq + 1, now_ms(), pose, skeletons, hands, blendshapes)
        self._publish_pose(m, t_source, pose)

    def _subject(self, m: SceneMesh) -> str:
        return TRANSFORMS if m is self.default else transforms_subject(m.id)

    def _publish_pose(self, m: SceneMesh, t_source: float, pose: GraphPose | None = None) -> None:
        m.seq += 1
        pose = m.pose if pose is None else pose
        block = pack_transforms(m.seq, m.id, pose.node_matrices(m.graph.nodes), t_source, now_ms())
        self.hub.publish(Frame(self._subject(m), m.seq, t_source, block))

    def transforms_block(self, mesh_id: int | None = None) -> bytes:
        """A mesh's current pose as a transform block (sent to a viewer when it connects)."""
        m = self.scene_mesh(mesh_id)
        return pack_transforms(m.seq, m.id, m.pose.node_matrices(m.graph.nodes), now_ms(), now_ms())

    def transforms_blocks(self) -> list[bytes]:
        """Every mesh's current pose, the default mesh's first."""
        return [self.transforms_block(i) for i in self.meshes]

    def publish_rest(self) -> None:
        """Publish again the pose of each mesh nobody possesses (a remote scene's heartbeat: gateways that
        joined late get every mesh's pose)."""
        for m in self.meshes.values():
            if m.rig is None:
                self.hub.publish(Frame(self._subject(m), m.seq, now_ms(), self.transforms_block(m.id)))

    def close(self) -> None:
        """Stop every mesh's solver."""
        for m in self.meshes.values():
            m.solver.close()

    # --- state for the pages ------------------------------------------------------------------------
    def mesh_state(self, m: SceneMesh) -> dict:
        attached = {c: np.asarray(j).tolist() for c, j in zip(m.possessors, m.attached)} if m.rig is not None else {}
        return {"id": m.id, "name": m.name, "url": f"/api/mesh/{m.id}", "nodes": m.graph.node_count,
                "vertices": int(len(m.mesh.vertices)), "up": m.upright.up if m.upright else "y",
                "up_reason": m.upright.reason if m.upright else "", "placement": m.placement.as_dict(),
                "possessors": list(m.possessors) if m.rig is not None else [],
                "solve_ms": float(np.median(m.solve_ms)) if m.solve_ms else None, "attached": attached}

    def state(self) -> dict:
        skipped = self._skeletons.skipped if self._skeletons else 0
        meshes = [self.mesh_state(m) for m in self.meshes.values()]
        attached = {c: j for mesh in meshes for c, j in mesh.pop("attached").items()}
        solve_cpu = [ms for m in self.meshes.values() for ms in m.solve_cpu_ms]
        solve_ms = [ms for m in self.meshes.values() for ms in m.solve_ms]
        default = {k: v for k, v in meshes[0].items() if k not in ("placement", "possessors", "solve_ms")}
        return {
            "type": "state",
            "mesh": default,  # the default mesh, as a scene of one mesh reported it
            "placement": meshes[0]["placement"],
            "meshes": meshes,
            "users": [{"client": u.client, "possessing": u.bind is not None, "mesh": u.mesh, "subset": u.subset, "hand": u.hand,
                       "frames": u.frames, "attached": attached.get(u.client, [])}
                      for u in self.users.values()],
            "recording": self._recording_dir is not None,
            "joint_map": None if self.joint_map is None else {"name": self.joint_map.path,
                                                             "sources": len(self.joint_map.sources)},
            "solve_ms": float(np.median(solve_ms)) if solve_ms else None,
            "solve_cpu_ms": float(np.median(solve_cpu)) if solve_cpu else None,
            "solve_cpu_ms_p99": float(np.percentile(solve_cpu, 99)) if solve_cpu else None,
            "solves_stopped": sum(m.stopped for m in self.meshes.values()),
            "error": self.last_error,
            # frames in: all that reached the scene; merged: superseded before a solve used them (in the
            # subscription's slot or as a user's newest frame); late: older than the user's newest
            "skeleton_frames": self.frames_in + skipped,
            "dropped": {"merged": self.superseded + skipped, "late": self.late},
        }

    def publish_state(self) -> None:
        self._state_seq += 1
        self.hub.publish(Frame(STATE, self._state_seq, now_ms(), json.dumps(self.state()).encode()))

    # --- takes --------------------------------------------------------------------------------------
    def start_recording(self, folder: str | Path | None = None) -> Path:
        """Record every mesh's solved frames to a take log each in `folder` (a temporary folder by default),
        flushed per frame; returns the folder."""
        self._close_recordings()
        folder = Path(tempfile.mkdtemp(prefix="kinetre-recording-")) if folder is None else Path(folder)
        self._recording_dir = folder
        for m in self.meshes.values():
            m.recording = TakeLog(self._log_path(m))
        self.publish_state()
        return folder

    def _log_path(self, m: SceneMesh) -> Path:
        """The default mesh's take log is take.log.jsonl (what is left on disk if the scene is killed); the
        others' take-mesh<id>.log.jsonl beside it."""
        return self._recording_dir / ("take.log.jsonl" if m is self.default else f"take-mesh{m.id}.log.jsonl")

    def _close_recordings(self) -> list[tuple[SceneMesh, TakeLog]]:
        logs = [(m, m.recording) for m in self.meshes.values() if m.recording is not None]
        for m, log_ in logs:
            log_.close()
            m.recording = None
        return logs

    def stop_recordings(self) -> dict[int, list[TakeFrame]]:
        """Each mesh's recorded frames by mesh id (the default mesh's first), read back from the take logs
        (which are then removed)."""
        for m in self.meshes.values():
            self._flush(m)  # a pose held back for the next solve's request was solved while recording
        folder, self._recording_dir = self._recording_dir, None
        logs = self._close_recordings()
        self.publish_state()
        takes = {m.id: [TakeFrame(*frame[1:]) for frame in read_take_log(log_.path)] for m, log_ in logs}
        if folder is not None and folder.name.startswith("kinetre-recording-"):  # ours: a caller's is left alone
            shutil.rmtree(folder, ignore_errors=True)
        return takes

    def stop_recording(self) -> list[TakeFrame]:
        """The default mesh's recorded frames (see `stop_recordings`)."""
        default = self.default.id
        return self.stop_recordings().get(default, [])


def resample(take: list[TakeFrame], fps: float) -> list[TakeFrame]:
    """The take at a fixed rate: frame k is the newest solved frame at time t0 + k / fps (held, not blended)."""
    if not take:
        return []
    times = np.array([f.t for f in take])
    count = int((times[-1] - times[0]) / 1000.0 * fps) + 1
    picks = np.searchsorted(times, times[0] + np.arange(count) * 1000.0 / fps, side="right") - 1
    return [take[i] for i in picks]


def check_hand(value) -> str | None:
    """A possessing hand from a client message: null, "left" or "right"."""
    if value is None or value in SIDES:
        return value
    raise ProtocolError(f"hand must be null, \"left\" or \"right\", got {value!r}")


def check_subset(value) -> str | list | None:
    """A subset from a client message: null, a name, or a list of names."""
    if value is None or isinstance(value, str):
        return value or None
    if isinstance(value, list) and value and all(isinstance(v, str) for v in value):
        return value
    raise ProtocolError(f"subset must be null, a name or a list of names, got {value!r}")
