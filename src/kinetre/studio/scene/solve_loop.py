"""Each mesh's solves, and the one place a mesh's pose goes out.

While anyone possesses a mesh, its graph pose is solved from all its possessing users' newest frames at once
(their constraints add up in one energy; the solve runs in the mesh's solver, solve_worker.py) and its node
matrices are published on the mesh's transforms subject. Frames that arrive while a solve runs are merged
latest-wins (users.py), so a slow solve lowers the frame rate instead of building a queue.

A solve starts in the call that brings its frame in (`SolveLoops.wake`), and its pose goes out in the call
that reads the solver's answer: a solve loop that waited on an event would start each solve only once
the event loop came round to it, behind every other page's message read in the same turn (under twenty
cameras sending at once, that was most of the time between a frame's arrival and its solve).
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

GATHER_S = 0.010  # longest wait for another possessing user's frame that is due (see SolveLoops.gather_deadline)
GATHER_SLACK_S = 0.005  # how late a user's frame may be (arrival jitter) and still be waited for
LATE_S = 0.004  # a frame this long in the scene yields after its solve's next step (see SolveLoops.begin)


class Publisher:
    """Where every mesh's pose goes out: a solved pose with `solved` (recorded first), a pose set otherwise (at
    rest, a mesh added) with `publish`."""

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

    def solved(self, m: SceneMesh, pose: GraphPose, t_source: float, users: list[User]) -> None:
        """Mesh `m`'s newly solved pose: recorded, with what it was solved from, then published."""
        m.pose = pose
        take_log = self.recording.logs.get(m.id)
        if take_log is not None:  # on disk before any viewer sees the frame
            take_log.append(m.seq + 1, now_ms(), pose, {u.client: u.latest for u in users},
                            {u.client: u.hands for u in users if u.hands is not None},
                            {u.client: u.blendshapes for u in users if u.blendshapes is not None})
        self.publish(m, t_source, pose)


class SolveLoops:
    """Each mesh's solves while `running`: one in flight per mesh (`SceneMesh.solving`), the next started as
    soon as it is asked for (`wake`) and can start. `rebuild(m)` attaches mesh `m`'s possessors anew (after
    its solver was lost)."""

    def __init__(self, users: Users, meshes: Meshes, publisher: Publisher,
                 rebuild: Callable[[SceneMesh], Awaitable[None]]):
        self.users, self.meshes, self.publisher, self.rebuild = users, meshes, publisher, rebuild
        self.running = False
        self.last_error = ""

    def wake(self, m: SceneMesh) -> None:
        """A possessor's newer frame: a running solve yields to it (solve_worker.yielding), and the next solve
        starts now if it can."""
        m.dirty.set()
        m.solver.newer_frame()
        self.kick(m)

    def start(self, m: SceneMesh) -> None:
        """Mesh `m` joined the running scene: solve what waits."""
        self.kick(m)

    def stop_all(self) -> None:
        """No further solve starts (those in flight end and publish)."""
        self.running = False
        for m in self.meshes.values():
            m.wait_gather(None)

    def retire(self, m: SceneMesh) -> None:
        """A mesh left the scene: its solver closes after the solve in flight (cutting that would leave the
        solver's reply unread), unless a mesh in the scene still uses it."""
        m.wait_gather(None)
        if m.solving is None:
            self.close_solver(m)

    def close_solver(self, m: SceneMesh) -> None:
        if not any(other.solver is m.solver for other in self.meshes.values()):
            m.solver.close()

    def kick(self, m: SceneMesh) -> None:
        """Start mesh `m`'s next solve now, in the caller's call, if one is asked for (`m.dirty`) and none is in
        flight or attaching; or, when another possessor's frame is due within moments, once it came or
        `gather_deadline` passed."""
        if not self.can_start(m):
            return
        now = time.monotonic()
        deadline = self.gather_deadline(m, now)
        if deadline is not None:
            if m.gather is None:  # the next possessor's frame, or this deadline, starts the solve
                m.wait_gather(asyncio.get_running_loop().call_later(deadline - now, self.gathered, m))
            return
        self.begin_live(m)

    def gathered(self, m: SceneMesh) -> None:
        """The wait for a possessor's due frame is over: solve what came."""
        m.gather = None
        if self.can_start(m):
            self.begin_live(m)

    def can_start(self, m: SceneMesh) -> bool:
        """A live solve of mesh `m` is asked for and may start now: the scene runs and holds the mesh, and no
        solve is in flight or attach under way."""
        return self.running and m.solving is None and not m.lock.locked() and m.dirty.is_set() and \
            self.meshes.holds(m)

    def begin_live(self, m: SceneMesh) -> None:
        try:
            self.begin(m, LATE_S, None)
        except Exception as exc:  # one bad frame must not stop the scene for everybody
            self.failed(exc)

    def failed(self, exc: BaseException) -> None:
        self.last_error = f"solve failed: {type(exc).__name__}: {exc}"
        log.error("solve failed", exc_info=exc)

    def resume_when_quiet(self, m: SceneMesh) -> None:
        """A solve was cut short and no newer frame waits: once its users' next frames are overdue (they
        stopped sending, or paused), the same frame is solved on from the pose it reached, uncut (see
        `begin`), so a user's last frame ends solved. While frames keep coming, the next one goes on from
        that pose anyway: an uncut solve of a frame about to be superseded would only hold it up."""
        users = [self.users[c] for c in m.possessors if c in self.users]
        seqs = [u.seq for u in users]
        wait = max((u.period for u in users if u.period), default=0.0) + GATHER_SLACK_S

        def resume() -> None:
            if self.meshes.holds(m) and not m.dirty.is_set() and [u.seq for u in users] == seqs:
                m.dirty.set()
                self.kick(m)
        asyncio.get_running_loop().call_later(wait, resume)

    def gather_deadline(self, m: SceneMesh, now: float) -> float | None:
        """How long to wait, before solving, for the mesh's other possessing users' frames that are due now
        (None: solve at once).

        Every solve takes all possessors' newest frames. When one user's frame arrives and another's is due
        with it, solving at once would make that frame wait for the whole running solve and then its own;
        waiting for it costs the first frame only the gap, and one solve serves both. A user is waited for
        (at most `GATHER_S` after the first new frame's arrival) when its next frame was sent in the same tick
        as the newest new frame: stamped, by the senders' clocks, within a quarter of its frame period of it
        (people in one camera, or cameras ticking together: their frames come a message apart, however much
        their arrival times wander). Otherwise, only while its next frame is expected (from its arrivals)
        within half a recent solve's time of the first new frame's arrival, and not once it is overdue (a
        user who stopped sending delays nothing).
        """
        users = [self.users[c] for c in m.possessors if c in self.users]
        fresh = [u.arrived for u in users if u.used != u.seq]
        if not fresh or len(fresh) == len(users):
            return None
        stamp = max(u.t for u in users if u.used != u.seq)  # ms, the sender's clock
        if any(u.used == u.seq and u.period and abs(u.t + 1000 * u.period - stamp) <= 250 * u.period
               for u in users):
            return min(fresh) + GATHER_S
        solve_s = float(np.median(m.solve_ms[-15:])) / 1000 if m.solve_ms else GATHER_S
        # frames a and b arriving g apart, a solve taking S: solving a at once ends b's wait at 2S - g, waiting
        # for b ends both at g + S (and spares a solve): better while g < S / 2
        limit = min(fresh) + min(GATHER_S, solve_s / 2)
        due = [u.arrived + u.period for u in users if u.used == u.seq and u.period]
        if not any(now - GATHER_SLACK_S <= d <= limit for d in due):
            return None
        return limit  # or sooner: every user's new frame wakes the wait

    async def solve(self, m: SceneMesh, late: float | None) -> GraphPose | None:
        """Solve mesh `m` now with its possessing users' newest frames, after the solve in flight; its pose,
        published (see `begin`), or None when nobody drives it. Errors are raised here."""
        async with m.lock:  # no solve starts meanwhile, and none attaches
            await m.idle()
            done = self.begin(m, late, asyncio.get_running_loop().create_future())
            return None if done is None else await done

    def begin(self, m: SceneMesh, late: float | None, done: asyncio.Future | None) -> asyncio.Future | None:
        """Send mesh `m`'s possessing users' newest frames to its solver; when the solve ends, in the call that
        reads its answer, its pose is recorded and published and the next solve starts if one is asked for.
        `done` (None: the live loop, which reports errors in `last_error`) gets the pose or the error.

        The solver yields after a Gauss-Newton step (`solve_worker.yielding`) to a newer frame, or once the
        oldest frame it solves has been `late` seconds in the scene (the live loop: `LATE_S`): its pose goes
        out at once and the next frame goes on from it (the live loop solves the same frame on from it,
        without `late`, when no newer one came in its users' frame period: `resume_when_quiet`), instead of
        every viewer's picture waiting for the rest of a long solve."""
        m.dirty.clear()  # the frames in so far go into this solve
        m.wait_gather(None)
        users = [self.users[c] for c in m.possessors if c in self.users]
        if m.rig is None or not self.meshes.holds(m) or len(users) != len(m.possessors):
            if done is not None:
                done.set_result(None)
            return done
        frames = [u.driving(m.placement) for u in users]
        # when the frames were all solved before (a solve that was cut short goes on), there is no lateness to
        # cut for again: only a newer frame stops the solve
        arrived = min((u.arrived for u in users if u.used != u.seq), default=None)
        for u in users:
            u.used = u.seq
        t_source = max(u.t for u in users)
        loop = asyncio.get_running_loop()
        # a frame already overdue yields after its first step: say so with the request, not from a timer that
        # may fire only after the whole solve on a busy machine
        due = None if late is None or arrived is None else arrived + late - time.monotonic()
        overdue = due is not None and due <= 0.0
        timer = loop.call_later(due, m.solver.newer_frame) if due is not None and not overdue else None
        m.solving = solving = loop.create_future()
        start = time.perf_counter()

        def ended(outcome: GraphPose | BaseException) -> None:
            if timer is not None:
                timer.cancel()
            m.solving = None
            try:
                if isinstance(outcome, BaseException):
                    if isinstance(outcome, SolverLost):
                        m.rig = None  # the worker died: re-attach everybody at their current pose
                        loop.create_task(self.rebuild(m))
                    raise outcome
                m.solve_ms[:] = (m.solve_ms + [1000 * (time.perf_counter() - start)])[-60:]
                m.solve_cpu_ms[:] = (m.solve_cpu_ms + [m.solver.cpu_ms])[-600:]
                stopped = bool(getattr(m.solver, "stopped", False))
                m.stopped += stopped
                self.publisher.solved(m, outcome, t_source, users)
                if done is not None:
                    done.set_result(outcome)
                elif stopped and not m.dirty.is_set():
                    self.resume_when_quiet(m)
            except (Exception, asyncio.CancelledError) as exc:  # the solve's error, or its pose's recording
                if isinstance(exc, asyncio.CancelledError):  # the scene is closing
                    if done is not None:
                        done.cancel()
                elif done is None:
                    self.failed(exc)
                elif not done.done():
                    done.set_exception(exc)
            finally:
                solving.set_result(None)
                if not self.meshes.holds(m):
                    self.close_solver(m)
                else:
                    self.kick(m)

        try:
            m.solver.submit(frames if len(frames) > 1 else frames[0], overdue, ended)
        except Exception as exc:  # the request could not go out: the same as a solve that failed
            ended(exc)
        return done
