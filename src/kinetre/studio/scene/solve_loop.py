"""Each mesh's solve loop, and the one place a mesh's pose goes out.

While anyone possesses a mesh, its graph pose is solved from all its possessing users' newest frames at once
(their constraints add up in one energy; the solve runs in the mesh's solver, solve_worker.py) and its node
matrices are published on the mesh's transforms subject. Frames that arrive while a solve runs are merged
latest-wins (users.py), so a slow solve lowers the frame rate instead of building a queue.
"""
from __future__ import annotations

import asyncio
import logging
import time
from typing import Awaitable, Callable

import numpy as np

from ...deform.pose import GraphPose
from ...wire.transforms import pack_transforms
from ..channels import Channels, Frame, now_ms
from ..subjects import transforms_subject
from .meshes import Meshes, SceneMesh
from .solve_worker import SolverLost
from .takes import Recording
from .users import User, Users

log = logging.getLogger("kinetre.studio")

GATHER_S = 0.010  # longest wait for another possessing user's frame that is due (see SolveLoops.gather)
GATHER_SLACK_S = 0.005  # how late a user's frame may be (arrival jitter) and still be waited for
LATE_S = 0.004  # a frame this long in the scene yields after its solve's next step (see SolveLoops.solve)


class Publisher:
    """Where every mesh's pose goes out: a solved pose is held (`hold`) and goes out, recorded first, with
    `flush`; a pose set otherwise (at rest, a mesh added) goes out at once with `publish`."""

    def __init__(self, hub: Channels, recording: Recording):
        self.hub, self.recording = hub, recording

    def subject(self, m: SceneMesh) -> str:
        return transforms_subject(m.id)

    def block(self, m: SceneMesh) -> bytes:
        """Mesh `m`'s current pose as a transform block (sent to a viewer when it connects)."""
        return pack_transforms(m.seq, m.id, m.pose.node_matrices(m.graph.nodes), now_ms(), now_ms())

    def publish(self, m: SceneMesh, t_source: float, pose: GraphPose | None = None) -> None:
        """A new transform block of mesh `m`'s pose (`pose`, else its current one)."""
        m.seq += 1
        pose = m.pose if pose is None else pose
        block = pack_transforms(m.seq, m.id, pose.node_matrices(m.graph.nodes), t_source, now_ms())
        self.hub.publish(Frame(self.subject(m), m.seq, t_source, block))

    def republish(self, m: SceneMesh) -> None:
        """Mesh `m`'s current pose again, under its last block's number."""
        self.hub.publish(Frame(self.subject(m), m.seq, now_ms(), self.block(m)))

    def hold(self, m: SceneMesh, pose: GraphPose, t_source: float, users: list[User]) -> None:
        """A solved pose, with what it was solved from, to go out with the next `flush`."""
        m.pose = pose
        m.unpublished = (pose, t_source, {u.client: u.latest for u in users},
                         {u.client: u.hands for u in users if u.hands is not None},
                         {u.client: u.blendshapes for u in users if u.blendshapes is not None})

    def flush(self, m: SceneMesh) -> None:
        """Record and publish the mesh's last solved pose if it is not out yet."""
        if m.unpublished is None:
            return
        pose, t_source, skeletons, hands, blendshapes = m.unpublished
        m.unpublished = None
        take_log = self.recording.logs.get(m.id)
        if take_log is not None:  # on disk before any viewer sees the frame
            take_log.append(m.seq + 1, now_ms(), pose, skeletons, hands, blendshapes)
        self.publish(m, t_source, pose)


class SolveLoops:
    """One solve loop per mesh while `running`. `rebuild(m)` attaches mesh `m`'s possessors anew (after its
    solver was lost)."""

    def __init__(self, users: Users, meshes: Meshes, publisher: Publisher,
                 rebuild: Callable[[SceneMesh], Awaitable[None]]):
        self.users, self.meshes, self.publisher, self.rebuild = users, meshes, publisher, rebuild
        self.loops: dict[int, asyncio.Task] = {}
        self.running = False
        self.last_error = ""

    def wake(self, m: SceneMesh) -> None:
        """A possessor's newer frame: the loop solves it, and a running solve yields to it
        (solve_worker.yielding)."""
        m.dirty.set()
        m.solver.newer_frame()

    def start(self, m: SceneMesh) -> None:
        if self.running:
            self.loops[m.id] = asyncio.get_running_loop().create_task(self.loop(m))

    def stop_all(self) -> None:
        self.running = False
        for task in self.loops.values():
            task.cancel()
        self.loops.clear()

    def retire(self, m: SceneMesh) -> None:
        """A mesh left the scene: its solve loop ends after the solve in flight (cancelling that would leave
        the solver's reply unread), then its solver, unless a mesh in the scene still uses it."""
        if self.loops.pop(m.id, None) is not None:
            m.dirty.set()  # the loop wakes, sees the mesh gone, and ends
        else:
            self.close_solver(m)

    def close_solver(self, m: SceneMesh) -> None:
        if not any(other.solver is m.solver for other in self.meshes.values()):
            m.solver.close()

    async def loop(self, m: SceneMesh) -> None:
        try:
            while self.meshes.holds(m):
                await m.dirty.wait()
                if not self.meshes.holds(m):
                    break
                await self.gather(m)
                try:
                    pose = await self.solve(m, LATE_S)
                    if pose is not None and getattr(m.solver, "stopped", False) and not m.dirty.is_set():
                        self.resume_when_quiet(m)
                except Exception as exc:  # one bad frame must not stop the scene for everybody
                    self.last_error = f"solve failed: {type(exc).__name__}: {exc}"
                    log.exception("solve failed")
        finally:
            if not self.meshes.holds(m):
                self.close_solver(m)

    def resume_when_quiet(self, m: SceneMesh) -> None:
        """A solve was cut short and no newer frame waits: once its users' next frames are overdue (they
        stopped sending, or paused), the same frame is solved on from the pose it reached, uncut (see
        `solve`), so a user's last frame ends solved. While frames keep coming, the next one goes on from
        that pose anyway: an uncut solve of a frame about to be superseded would only hold it up."""
        users = [self.users[c] for c in m.possessors if c in self.users]
        seqs = [u.seq for u in users]
        wait = max((u.period for u in users if u.period), default=0.0) + GATHER_SLACK_S

        def resume() -> None:
            if self.meshes.holds(m) and not m.dirty.is_set() and [u.seq for u in users] == seqs:
                m.dirty.set()
        asyncio.get_running_loop().call_later(wait, resume)

    async def gather(self, m: SceneMesh) -> None:
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
            deadline = self.gather_deadline(m, time.monotonic())
            if deadline is None:
                return
            self.publisher.flush(m)  # no solve starts yet: the last pose goes out now
            try:
                await asyncio.wait_for(m.dirty.wait(), deadline - time.monotonic())
            except asyncio.TimeoutError:
                return

    def gather_deadline(self, m: SceneMesh, now: float) -> float | None:
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

    async def solve(self, m: SceneMesh, late: float | None) -> GraphPose | None:
        """Solve mesh `m` with its possessing users' newest frames and publish its node matrices.

        The solver yields after a Gauss-Newton step (`solve_worker.yielding`) to a newer frame, or once the
        oldest frame it solves has been `late` seconds in the scene (the live loop: `LATE_S`): its pose is
        published at once and the next frame goes on from it (the live loop solves the same frame on from it,
        without `late`, when no newer one came in its users' frame period: `resume_when_quiet`), instead of every viewer's picture waiting for the rest of a
        long solve. A solved pose goes out as soon as its solve ends, before the next solve is prepared: deferring
        it behind the next request put up to 2 ms on a fifth of the frames under load."""
        publisher = self.publisher
        async with m.lock:
            users = [self.users[c] for c in m.possessors if c in self.users]
            if m.rig is None or not self.meshes.holds(m) or len(users) != len(m.possessors):
                publisher.flush(m)
                return None
            frames = [u.driving(m.placement) for u in users]
            # when the frames were all solved before (the loop goes on with a solve that was cut short), there
            # is no lateness to cut for again: only a newer frame stops the solve
            arrived = min((u.arrived for u in users if u.used != u.seq), default=None)
            for u in users:
                u.used = u.seq
            t_source = max(u.t for u in users)
            start = time.perf_counter()
            loop = asyncio.get_running_loop()
            if m.unpublished is not None:
                loop.call_soon(publisher.flush, m)  # runs once the solve's request is out
            # a frame already overdue yields after its first step whenever the event loop next runs: say so with
            # the request, not from a timer that may fire only after the whole solve on a busy machine
            due = None if late is None or arrived is None else arrived + late - time.monotonic()
            overdue = due is not None and due <= 0.0
            timer = loop.call_later(due, m.solver.newer_frame) if due is not None and not overdue else None
            try:
                pose = await m.solver.solve(frames if len(frames) > 1 else frames[0], overdue)
            except SolverLost:
                m.rig = None  # the worker died: re-attach everybody at their current pose
                loop.create_task(self.rebuild(m))
                raise
            finally:
                if timer is not None:
                    timer.cancel()
            m.solve_ms[:] = (m.solve_ms + [1000 * (time.perf_counter() - start)])[-60:]
            m.solve_cpu_ms[:] = (m.solve_cpu_ms + [m.solver.cpu_ms])[-600:]
            m.stopped += bool(getattr(m.solver, "stopped", False))
            publisher.hold(m, pose, t_source, users)
            publisher.flush(m)
            return pose
