"""The scene's meshes and where each stands in the room.

Each mesh has its own graph, placement, rig and solver; each user possesses at most one of them. A mesh is
placed by hand (`place`), scaled to a user's height where the user stands (`fit`, the paper's scale to
height), or, when added, stood beside the others (`placement.beside`).
"""
from __future__ import annotations

import asyncio
import itertools
from dataclasses import dataclass, field

import numpy as np

from ...deform.pose import GraphPose
from ...errors import AttachError, KinetreError
from ...graph.graph import DeformationGraph
from ...mesh.mesh import Mesh
from ...mesh.upright import Upright
from ...motion.fit import yaw_rotation
from ...skeleton.models import Skeleton
from ..placement import Placement
from ..protocol import ProtocolError, check_placement
from .users import User


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
    solve_ms: list[float] = field(default_factory=list)  # recent solve round trips (wall), for the state line
    solve_cpu_ms: list[float] = field(default_factory=list)  # the last 600 solves' CPU time in the solver
    stopped: int = 0  # solves that yielded to a newer frame after a step (solve_worker.yielding)
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)  # held by an attach, or an awaited solve
    dirty: asyncio.Event = field(default_factory=asyncio.Event)  # a solve is asked for (a possessor's new frame)
    solving: asyncio.Future | None = None  # the solve in flight, done once its pose is out
    gather: asyncio.TimerHandle | None = None  # the end of a wait for a possessor's due frame (solve_loop)

    def __post_init__(self):
        if self.pose is None:
            self.pose = GraphPose.identity(self.graph.node_count)

    async def idle(self) -> None:
        """Once no solve is in flight (its pose is out)."""
        while self.solving is not None:
            await asyncio.wait([self.solving])

    def wait_gather(self, handle: asyncio.TimerHandle | None) -> None:
        """The timer that ends the wait for a due frame (None: no wait), instead of any before."""
        if self.gather is not None:
            self.gather.cancel()
        self.gather = handle

    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """World-space (min, max) of the mesh at rest, as placed."""
        p = self.placement
        world = p.scale * self.mesh.vertices @ p.rotation.T + np.asarray(p.position)
        return world.min(axis=0), world.max(axis=0)


class Meshes(dict):
    """The scene's meshes by id, in the order they were added."""

    def __init__(self):
        super().__init__()
        self._ids = itertools.count(1)

    def next_id(self) -> int:
        return next(self._ids)

    @property
    def first(self) -> SceneMesh:
        return next(iter(self.values()))

    def named(self, mesh_id: int | None) -> SceneMesh:
        """Mesh `mesh_id` (None: the first); MeshError (404) naming the meshes held otherwise."""
        if mesh_id is None:
            return self.first
        m = self.get(mesh_id)
        if m is None:
            raise MeshError(f"no mesh {mesh_id} in the scene (its meshes: {', '.join(str(i) for i in self)})", 404)
        return m

    def holds(self, m: SceneMesh) -> bool:
        """Whether `m` is still in the scene (not removed or replaced)."""
        return self.get(m.id) is m

    def replace(self, old: SceneMesh, new: SceneMesh) -> None:
        """`new` in `old`'s place in the order."""
        items = [(new.id, new) if i == old.id else (i, m) for i, m in self.items()]
        self.clear()
        self.update(items)


def place(m: SceneMesh, scale: float, position, yaw: float) -> None:
    """Stand mesh `m` at `position` (metres), turned by `yaw` (radians) about +Y, scaled by `scale`."""
    m.placement = Placement(*check_placement(scale, position, yaw))


def fit(m: SceneMesh, user: User | None) -> None:
    """Scale mesh `m` to the user's height and stand it where the user stands (paper: scale to height)."""
    if user is None or user.latest is None or user.latest.tracked.sum() < 2:
        raise AttachError("no tracked skeleton yet: step in front of the camera first")
    sk = user.latest
    height = sk.height
    mesh_height = float(np.ptp(m.mesh.vertices[:, 1]))
    if height <= 0.3 or mesh_height <= 0:
        raise AttachError(f"the tracked skeleton is {height:.2f} m tall: show your whole body to the camera")
    fitted = Placement.fitted(sk, m.mesh, m.placement.yaw)
    try:  # a skeleton in the room, but a mesh that would need a scale out of bounds to match it
        check_placement(fitted.scale, fitted.position, fitted.yaw)
    except ProtocolError as e:
        raise AttachError(f"fit: the mesh cannot be scaled to this skeleton ({e})") from None
    m.placement = fitted


def stand_in(skeleton: Skeleton, source, placement: Placement) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) that moves a joint-map source's person, turned by its `yaw`, from where they stand to the
    mesh's centre plus its `offset` (metres, turned with the mesh, placed by `placement`): two people anywhere
    in one camera's view become the front and back legs of one horse, as two separate captures would in a
    joint take."""
    root = skeleton.positions[0] if skeleton.tracked[0] else skeleton.positions[skeleton.tracked].mean(axis=0)
    root = np.array([root[0], 0.0, root[2]])
    turn = yaw_rotation(source.yaw)
    target = np.asarray(placement.position, dtype=np.float64) + placement.rotation @ source.offset
    target[1] = 0.0  # only across the floor: the person keeps their height
    return turn, target - turn @ root
