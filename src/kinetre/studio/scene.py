"""The server-side scene: mesh, graph, rigs and solver (the render component, minus the rendering).

It subscribes to every skeleton subject (SKELETONS), keeps each user's newest frame and, while anyone
possesses the mesh, solves the graph pose from all possessing users at once (their constraints add up in
one energy) and publishes the node matrices on TRANSFORMS. Frames that arrive while a solve
runs are merged latest-wins, so a slow solve lowers the frame rate instead of building a queue.
"""
from __future__ import annotations

import asyncio
import json
import logging
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..deform.pose import GraphPose
from ..errors import AttachError
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
from .placement import Placement
from .protocol import ProtocolError, SkeletonFrame, parse_frame, parse_message
from .solve_worker import InlineSolver, SolverLost
from .subjects import SKELETONS, STATE, TRANSFORMS, last_token
from .takelog import TakeLog, read_take_log

log = logging.getLogger("kinetre.studio")

GATHER_S = 0.010  # longest wait for another possessing user's frame that is due (see Scene._gather)
GATHER_SLACK_S = 0.005  # how late a user's frame may be (arrival jitter) and still be waited for
LATE_S = 0.015  # a frame this long in the scene yields after its solve's next step (see Scene.solve_once)


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


class Scene:
    """Mesh + graph + rig + solver, driven by skeleton channels.

    Parameters
    ----------
    hub : Channels
    mesh : Mesh
        In metres, standing on y = 0 (see `placement.standing_mesh`).
    graph : DeformationGraph
        Built on `mesh`.
    name : str
        Shown in the page.
    """

    def __init__(self, hub: Channels, mesh: Mesh, graph: DeformationGraph, name: str = "mesh", solver=None,
                 upright: Upright | None = None):
        self.hub = hub
        self.solver = solver if solver is not None else InlineSolver()  # SolveWorker: the rig in its own process
        self.attached: list = []  # per possessor, the joints that attached
        self.users: dict[str, User] = {}
        self.placement = Placement()
        self.mesh_id = 0
        self.rig = None  # the solver holding the rig while anyone possesses the mesh
        self.possessors: list[str] = []  # order of the skeletons given to the rig
        self.pose: GraphPose | None = None
        self.seq = 0
        self.recording: TakeLog | None = None
        self.last_error = ""
        self.solve_ms: list[float] = []  # recent solve round trips (wall), for the state line
        self.solve_cpu_ms: list[float] = []  # the last 600 solves' CPU time in the solver (median, p99)
        self.stopped = 0  # solves that yielded to a newer frame after a step (solve_worker.yielding)
        self.joint_map = None  # a JointMap: the n-th user to possess drives with the joints sources[n] keeps
        self._lock = asyncio.Lock()  # one attach/solve at a time; both run in a worker thread
        self._dirty = asyncio.Event()
        self._state_seq = 0
        self.late = 0  # skeleton frames older than the user's newest (dropped)
        self.superseded = 0  # possessing users' frames replaced by a newer one before any solve used them
        self.frames_in = 0  # skeleton frames that reached the scene
        self._skeletons = None  # the subscription, whose `skipped` counts frames merged latest-wins
        # (pose, t_source, skeletons, hands, blendshapes) solved, published once the next solve is sent
        self._unpublished = None
        self.set_mesh(mesh, graph, name, upright)

    # --- mesh and placement -------------------------------------------------------------------------
    def set_mesh(self, mesh: Mesh, graph: DeformationGraph, name: str, upright: Upright | None = None) -> None:
        """Swap in a new mesh: everybody is released, the pose resets to rest. `upright`: the up axis it
        was stood on (shown on the page, which can override it)."""
        self._flush()
        self.mesh, self.graph, self.name, self.upright = mesh, graph, name, upright
        self.mesh_id += 1
        self.rig, self.possessors = None, []
        for user in self.users.values():
            user.bind = None
        self.pose = GraphPose.identity(graph.node_count)
        if self.recording is not None:
            self.recording.close()
        self.recording = None
        self._publish_pose(now_ms())
        self.publish_state()

    def place(self, scale: float, position, yaw: float) -> None:
        if not (np.isfinite(scale) and scale > 0):
            raise ProtocolError(f"scale must be a positive number, got {scale}")
        pos = tuple(float(v) for v in position)
        if len(pos) != 3 or not np.all(np.isfinite(pos)) or not np.isfinite(yaw):
            raise ProtocolError("position must be 3 finite numbers and yaw a finite number")
        self.placement = Placement(float(scale), pos, float(yaw))
        self.publish_state()

    def fit(self, client: str) -> None:
        """Scale the mesh to the user's height and stand it where the user stands (paper: scale to height)."""
        user = self.users.get(client)
        if user is None or user.latest is None or user.latest.tracked.sum() < 2:
            raise AttachError("no tracked skeleton yet: step in front of the camera first")
        sk = user.latest
        height = sk.height
        mesh_height = float(np.ptp(self.mesh.vertices[:, 1]))
        if height <= 0.3 or mesh_height <= 0:
            raise AttachError(f"the tracked skeleton is {height:.2f} m tall: show your whole body to the camera")
        self.placement = Placement.fitted(sk, self.mesh, self.placement.yaw)
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
            if self.users[client].bind is not None:
                self.users[client].bind = None
                self._rebuild_rig_later()
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
        if user.bind is not None:
            self._dirty.set()
            self.solver.newer_frame()  # a running solve yields to this frame (solve_worker.yielding)

    async def possess(self, client: str, subset=None, hand: str | None = None) -> None:
        """Bind the user's current pose (possession), or with `hand` ("left", "right") that hand's, fitted
        into the mesh from the shapes (a hand puppet); raises AttachError when nothing is near the mesh or
        the hand is not seen."""
        user = self.user(client)
        if hand is not None:
            await self._possess_by_hand(user, subset, hand)
            return
        if user.latest is None or not user.latest.tracked.any():
            raise AttachError("no tracked skeleton from this client yet: nothing to possess with")
        source = None
        if subset is None and self.joint_map is not None:
            others = sum(1 for c, u in self.users.items() if c != client and u.bind is not None)
            if others < len(self.joint_map.sources):
                source = self.joint_map.sources[others]
                subset = source.joint_names(user.latest.model, self.joint_map.path)
        if subset is not None:
            subset_mask(user.latest.model, subset)  # BadSkeletonError on an unknown name
        await self._bind(user, subset, None, None, self.stand_in(user.latest, source) if source is not None else None)

    async def _possess_by_hand(self, user: User, subset, hand: str) -> None:
        check_hand(hand)
        marks = user.hands
        if marks is None or not np.isfinite(marks[SIDES.index(hand)]).all():
            raise AttachError(f"no {hand} hand tracked from this client yet: show it to the camera")
        if subset is not None:
            subset_mask(HAND21, subset)  # BadSkeletonError on a name that is no part of a hand
        frame = Skeleton.from_positions(HAND21, marks[SIDES.index(hand)])
        # the shape fit searches for a second or so: off the event loop
        fitted = await asyncio.to_thread(fit_puppet, frame, self.mesh, self.graph.nodes)
        await self._bind(user, subset, hand, fitted, None)

    async def _bind(self, user: User, subset, hand: str | None, puppet, stand) -> None:
        """Possess with the user's newest frame, driven as given; back to what it was when attaching fails."""
        old = user.bind, user.subset, user.stand, user.hand, user.puppet
        user.subset, user.stand, user.hand, user.puppet = subset, stand, hand, puppet
        user.bind = user.driving(self.placement)
        try:
            await self._rebuild_rig()
        except Exception:
            user.bind, user.subset, user.stand, user.hand, user.puppet = old
            await self._rebuild_rig()
            raise
        self.publish_state()

    def stand_in(self, skeleton: Skeleton, source) -> tuple[np.ndarray, np.ndarray]:
        """(R, t) that moves a joint-map source's person, turned by its `yaw`, from where they stand to the
        mesh's centre plus its `offset` (metres, turned with the mesh): two people anywhere in one camera's
        view become the front and back legs of one horse, as two separate captures would in a joint take."""
        root = skeleton.positions[0] if skeleton.tracked[0] else skeleton.positions[skeleton.tracked].mean(axis=0)
        root = np.array([root[0], 0.0, root[2]])
        turn = yaw_rotation(source.yaw)
        target = np.asarray(self.placement.position, dtype=np.float64) + self.placement.rotation @ source.offset
        target[1] = 0.0  # only across the floor: the person keeps their height
        return turn, target - turn @ root

    async def release(self, client: str) -> None:
        user = self.users.get(client)
        if user is None or user.bind is None:
            return
        user.bind = user.stand = user.hand = user.puppet = None
        await self._rebuild_rig()
        self.publish_state()

    async def set_subset(self, client: str, subset) -> None:
        """Change which joints drive; a possessing user re-binds with the new subset at the current pose (a
        hand puppet keeps its hand)."""
        user = self.user(client)
        if user.latest is not None and subset is not None and user.hand is None:
            subset_mask(user.latest.model, subset)
        if user.bind is not None:
            await self.possess(client, subset, user.hand)
        else:
            user.subset = subset
            self.publish_state()

    def _rebuild_rig_later(self) -> None:
        asyncio.get_running_loop().create_task(self._rebuild_rig())

    async def _rebuild_rig(self) -> None:
        async with self._lock:
            possessors = [c for c, u in self.users.items() if u.bind is not None]
            if not possessors:
                self._flush()
                self.rig, self.possessors = None, []
                self.pose = GraphPose.identity(self.graph.node_count)  # let go: back to rest
                self._publish_pose(now_ms())
                return
            users = [self.users[c] for c in possessors]
            binds = [u.bind for u in users]
            # a hand puppet reaches as far as its fit scaled it up (people: the attachment's own reach)
            reach = {} if all(u.puppet is None for u in users) else {
                "reach": [REACH * (1.0 if u.puppet is None else u.puppet.metre) for u in users],
                "bone_radius": [BONE_RADIUS * (1.0 if u.puppet is None else u.puppet.metre) for u in users]}
            self.attached = await self.solver.attach(self.graph, binds if len(binds) > 1 else binds[0], **reach)
            self.rig = self.solver
            self.possessors = possessors
        self._dirty.set()

    # --- the solve loop -----------------------------------------------------------------------------
    async def run(self) -> None:
        """Consume skeleton frames and publish transforms until cancelled."""
        sub = self._skeletons = self.hub.subscribe(SKELETONS)
        # each frame is taken in the publisher's own call (the server's handler, or the bus callback): a
        # hop through a task would make it wait a loop iteration, behind whatever else is ready
        sub.direct = self._take
        loop = asyncio.get_running_loop()
        helpers = [loop.create_task(self._feed(sub)), loop.create_task(self._heartbeat())]
        try:
            while True:
                await self._dirty.wait()
                await self._gather()
                try:
                    await self.solve_once(LATE_S)
                except Exception as exc:  # one bad frame must not stop the scene for everybody
                    self.last_error = f"solve failed: {type(exc).__name__}: {exc}"
                    log.exception("solve failed")
        finally:
            for task in helpers:
                task.cancel()
            sub.close()

    async def _gather(self) -> None:
        """Before solving, wait (briefly) for the other possessing users' frames that are due now.

        Every solve takes all possessors' newest frames. When one user's frame arrives and another's is due
        within half a solve (cameras ticking together, or by chance), solving at once would make that frame
        wait for the whole running solve and then its own; waiting for it costs the first frame only the
        gap, and one solve serves both. A user is waited for only while its next frame is expected (from its
        own frame period) within half a recent solve's time (at most `GATHER_S`) of the first new frame's
        arrival, and not once it is overdue (a user who stopped sending delays nothing).
        """
        while True:
            self._dirty.clear()  # the frames in so far go into this solve
            deadline = self._gather_deadline(time.monotonic())
            if deadline is None:
                return
            self._flush()  # no solve starts yet: the last pose goes out now
            try:
                await asyncio.wait_for(self._dirty.wait(), deadline - time.monotonic())
            except asyncio.TimeoutError:
                return

    def _gather_deadline(self, now: float) -> float | None:
        users = [self.users[c] for c in self.possessors if c in self.users]
        fresh = [u.arrived for u in users if u.used != u.seq]
        if not fresh or len(fresh) == len(users):
            return None
        solve_s = float(np.median(self.solve_ms[-15:])) / 1000 if self.solve_ms else GATHER_S
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

    async def solve_once(self, late: float | None = None) -> GraphPose | None:
        """Solve with every possessing user's newest frame and publish the node matrices.

        The solver yields after a Gauss-Newton step (`solve_worker.yielding`) to a newer frame, or once the
        oldest frame it solves has been `late` seconds in the scene (the live loop: `LATE_S`): its pose is published at once and the next
        frame goes on from it, instead of every viewer's picture waiting for the rest of a long solve. When
        a newer frame already waits as a solve ends, its pose is published once the next solve is under
        way: the solver then works while the transforms go out to every page (the embedded studio's
        fan-out, 3-8 ms), instead of waiting for them."""
        async with self._lock:
            if self.rig is None:
                self._flush()
                return None
            users = [self.users[c] for c in self.possessors if c in self.users]
            if len(users) != len(self.possessors):
                self._flush()
                return None
            frames = [u.driving(self.placement) for u in users]
            arrived = min((u.arrived for u in users if u.used != u.seq), default=time.monotonic())
            for u in users:
                u.used = u.seq
            t_source = max(u.t for u in users)
            start = time.perf_counter()
            loop = asyncio.get_running_loop()
            if self._unpublished is not None:
                loop.call_soon(self._flush)  # runs once the solve's request is out
            timer = None if late is None else loop.call_later(max(arrived + late - time.monotonic(), 0.0),
                                                              self.solver.newer_frame)
            try:
                pose = await self.solver.solve(frames if len(frames) > 1 else frames[0])
            except SolverLost:
                self.rig = None  # the worker died: re-attach everybody at their current pose
                self._rebuild_rig_later()
                raise
            finally:
                if timer is not None:
                    timer.cancel()
            self.solve_ms = (self.solve_ms + [1000 * (time.perf_counter() - start)])[-60:]
            self.solve_cpu_ms = (self.solve_cpu_ms + [self.solver.cpu_ms])[-600:]
            self.stopped += bool(getattr(self.solver, "stopped", False))
            self.pose = pose
            self._unpublished = (pose, t_source, {u.client: u.latest for u in users},
                                 {u.client: u.hands for u in users if u.hands is not None},
                                 {u.client: u.blendshapes for u in users if u.blendshapes is not None})
            if not any(u.seq != u.used for u in users):  # else once the next solve is sent
                self._flush()
            return pose

    def _flush(self) -> None:
        """Record and publish the last solve's pose if it is not out yet."""
        if self._unpublished is None:
            return
        pose, t_source, skeletons, hands, blendshapes = self._unpublished
        self._unpublished = None
        if self.recording is not None:  # on disk before any viewer sees the frame
            self.recording.append(self.seq + 1, now_ms(), pose, skeletons, hands, blendshapes)
        self._publish_pose(t_source, pose)

    def _publish_pose(self, t_source: float, pose: GraphPose | None = None) -> None:
        self.seq += 1
        pose = self.pose if pose is None else pose
        block = pack_transforms(self.seq, self.mesh_id, pose.node_matrices(self.graph.nodes), t_source, now_ms())
        self.hub.publish(Frame(TRANSFORMS, self.seq, t_source, block))

    def transforms_block(self) -> bytes:
        """The current pose as a transform block (sent to a viewer when it connects)."""
        return pack_transforms(self.seq, self.mesh_id, self.pose.node_matrices(self.graph.nodes), now_ms(),
                               now_ms())

    # --- state for the pages ------------------------------------------------------------------------
    def state(self) -> dict:
        skipped = self._skeletons.skipped if self._skeletons else 0
        attached = {}
        if self.rig is not None:
            attached = {c: np.asarray(j).tolist() for c, j in zip(self.possessors, self.attached)}
        return {
            "type": "state",
            "mesh": {"id": self.mesh_id, "name": self.name, "url": f"/api/mesh/{self.mesh_id}",
                     "nodes": self.graph.node_count, "vertices": int(len(self.mesh.vertices)),
                     "up": self.upright.up if self.upright else "y",
                     "up_reason": self.upright.reason if self.upright else ""},
            "placement": self.placement.as_dict(),
            "users": [{"client": u.client, "possessing": u.bind is not None, "subset": u.subset, "hand": u.hand,
                       "frames": u.frames, "attached": attached.get(u.client, [])}
                      for u in self.users.values()],
            "recording": self.recording is not None,
            "joint_map": None if self.joint_map is None else {"name": self.joint_map.path,
                                                             "sources": len(self.joint_map.sources)},
            "solve_ms": float(np.median(self.solve_ms)) if self.solve_ms else None,
            "solve_cpu_ms": float(np.median(self.solve_cpu_ms)) if self.solve_cpu_ms else None,
            "solve_cpu_ms_p99": float(np.percentile(self.solve_cpu_ms, 99)) if self.solve_cpu_ms else None,
            "solves_stopped": self.stopped,
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
    def start_recording(self, path: str | Path | None = None) -> Path:
        """Record solved frames to `path` (a temporary file by default), flushed per frame; returns the path."""
        if self.recording is not None:
            self.recording.close()
        if path is None:
            path = Path(tempfile.mkdtemp(prefix="kinetre-recording-")) / "take.log.jsonl"
        self.recording = TakeLog(path)
        self.publish_state()
        return self.recording.path

    def stop_recording(self) -> list[TakeFrame]:
        """The recorded frames, read back from the take log (which is then removed)."""
        self._flush()  # a pose held back for the next solve's request was solved while recording
        log_, self.recording = self.recording, None
        self.publish_state()
        if log_ is None:
            return []
        log_.close()
        take = [TakeFrame(*frame[1:]) for frame in read_take_log(log_.path)]
        if log_.path.parent.name.startswith("kinetre-recording-"):  # ours: a caller's path is left alone
            shutil.rmtree(log_.path.parent, ignore_errors=True)
        return take


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
