"""The rig lives in its own process, so a long solve never holds the server's interpreter.

The scene sends "attach" once per possession and then the newest frames, one solve in flight at a
time: frames that arrive meanwhile are merged latest-wins by the scene, so a slow solve lowers the
solve rate instead of building a queue, and the server's event loop only waits on a pipe. Only the
public `attach` / `Rig.solve` / `SolverSettings` API is used.

    InlineSolver   attach and solve in a thread of this process (unit tests, offline tools)
    SolveWorker    attach and solve in a child process (the studio and `kinetre scene`)

Both take a solve with `submit(skeletons, overdue, ended)`: the request goes out in the caller's call and
`ended` gets the pose (or the error) in the event-loop callback that reads the answer.
"""
from __future__ import annotations

import asyncio
import gc
import multiprocessing
import os
import time
from typing import Awaitable, Callable

import numpy as np

from ...deform.fast.live_stop import Yield
from ...deform.pose import GraphPose
from ...deform.solver import SolverSettings
from ...errors import KinetreError
from ...skeleton.rig import attach


class SolverLost(KinetreError):
    """The solve process died (killed, or out of memory); the scene starts a new one and re-attaches."""


Ended = Callable[[object], None]  # gets a solve's pose, or the exception that ended it


def submitted(solve: Awaitable, ended: Ended) -> None:
    """Run an awaitable solve in a task and hand its pose, or its error, to `ended`."""
    def report(task: asyncio.Task) -> None:
        if task.cancelled():  # the scene is closing
            ended(asyncio.CancelledError())
            return
        ended(task.exception() if task.exception() is not None else task.result())
    asyncio.get_running_loop().create_task(solve).add_done_callback(report)


class InlineSolver:
    """attach/solve in a worker thread of this process."""

    def __init__(self):
        self.rig = None
        self.cpu_ms = 0.0  # CPU time of the last solve
        self.stopped = False  # the last solve yielded to a newer frame (its pose is not converged)
        self._newer = np.zeros(1, np.uint8)  # set: a frame newer than the one being solved has arrived

    async def start(self) -> None:
        """Nothing to spawn: the solve runs in this process (`SolveWorker.start` spawns its process)."""

    async def attach(self, graph, skeletons, settings: SolverSettings = SolverSettings(),
                     **reach) -> list[np.ndarray]:
        """`kinetre.attach`; `reach`: its reach and bone_radius, when not a person's."""
        self.rig = await asyncio.to_thread(attach, graph, skeletons, settings=settings, **reach)
        return self.rig.attached_joints

    def newer_frame(self) -> None:
        """A newer frame waits: a long solve yields to it (see `yielding`)."""
        self._newer[0] = 1

    async def solve(self, skeletons, overdue: bool = False) -> GraphPose:
        """A pose for `skeletons`; `overdue`: the frame is late already, so the solve yields after its first
        step (see `yielding`), as it does when `newer_frame` is called while it runs."""
        self._newer[0] = int(overdue)

        def timed():
            start = time.thread_time()
            pose, self.stopped = solve_yielding(self.rig, skeletons, self._newer)
            self.cpu_ms = 1000 * (time.thread_time() - start)
            return pose
        return await asyncio.to_thread(timed)

    def submit(self, skeletons, overdue: bool, ended: Ended) -> None:
        """`solve`, its pose or error handed to `ended`."""
        submitted(self.solve(skeletons, overdue), ended)

    def detach(self) -> None:
        self.rig = None

    def close(self) -> None:
        self.rig = None


YIELD_AFTER_S = 0.0015  # CPU seconds a frame's solve may take before it yields to a newer frame


def yielding(newer: np.ndarray) -> Yield:
    """Rig.solve's `stop` for a live solve: a newer frame waits (`newer[0]` set, a uint8 view of the byte the
    scene sets) and this one has had its share of CPU. The frame then ends after its current Gauss-Newton
    step (PCG, read inside the numba loop; or an exact jump step) and publishes the pose reached, E
    lowered; the next frame goes on from it. Most frames converge before they would yield; the long ones
    (many creeping steps, a jump) go on over the next frames instead of making the newest frame wait."""
    return Yield.after_share(newer, YIELD_AFTER_S)


def solve_yielding(rig, skeletons, newer: np.ndarray) -> tuple[GraphPose, bool]:
    """`rig.solve` with `yielding(newer)`; also whether the solve yielded."""
    rig.last_report = None
    pose = rig.solve(skeletons, stop=yielding(newer))
    return pose, rig.last_report is not None and rig.last_report.stopped


def freeze_heap() -> None:
    """Move everything allocated so far (modules, numba's compiled kernels, the mesh) out of the garbage
    collector's reach, so that a full collection scans only what was allocated since: a full collection of
    the loaded studio's heap stalls the event loop, which puts every viewer's frame in the latency tail. Called once a process has started up."""
    gc.collect()
    gc.freeze()


def warm_up(frames: int = 3) -> None:
    """Attach and solve a few frames of the shipped sample (Spot, CMU walk) on a small graph.

    The solver's numba kernels compile (or load from the cache) on their first call; doing it here, before
    the first possession, keeps that pause out of a live take.
    """
    from importlib import resources

    from ...graph.build import build_graph
    from ...mesh.load import load_mesh
    from ...motion.bvh import load_bvh
    from ...motion.fit import fit_take

    data = resources.files("kinetre") / "data"
    mesh = load_mesh(str(data / "spot.obj"))
    take = load_bvh(str(data / "cmu_12_01_walk.bvh"))
    place = fit_take(take, mesh)
    rig = attach(place.graph(build_graph(mesh, nodes=32, seed=0)), place.skeleton(take.frame(0)))
    for i in range(1, frames + 1):
        rig.solve(place.skeleton(take.frame(8 * i)))


def _serve(conn, newer) -> None:
    """The child: one rig, requests answered in order until the pipe closes.

    Each reply is (status, value, CPU seconds this request took here, whether a solve yielded to a newer
    frame): the scene reports the solve's own CPU cost beside its round trip, which also counts waiting for
    a core on a busy machine. `newer` (a shared byte) is set by the scene when a newer frame arrives during
    a solve (Rig.solve's `stop`, read as a uint8 view inside the solver's numba loop).
    """
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        warm_up()
    except Exception:  # a warm-up that fails only costs the first real solve its compile time
        pass
    freeze_heap()
    flag = np.frombuffer(newer, dtype=np.uint8)  # the shared byte, as the solver's kernel reads it
    rig = None
    while True:
        try:
            request = conn.recv()
        except (EOFError, OSError):
            return
        start = time.thread_time()
        stopped = False
        try:
            if request[0] == "attach":
                _, graph, skeletons, settings, reach = request
                rig = attach(graph, skeletons, settings=settings, **reach)
                reply = ("ok", rig.attached_joints)
            elif request[0] == "solve":
                pose, stopped = solve_yielding(rig, request[1], flag)
                reply = ("ok", pose)
            else:  # "ping"
                reply = ("ok", os.getpid())
        except KinetreError as exc:
            reply = ("error", exc)
        except Exception as exc:  # a bug in a solve is reported to the scene, the process lives on
            reply = ("error", KinetreError(f"solve failed: {type(exc).__name__}: {exc}"))
        conn.send((*reply, time.thread_time() - start, stopped))


def _unwatch(loop: asyncio.AbstractEventLoop, fd: int) -> None:
    """Stop waiting for the pipe `fd` to be readable."""
    loop.remove_reader(fd)
    os.set_blocking(fd, True)  # uvloop made it non-blocking; Connection reads and writes expect blocking


class SolveWorker:
    """attach/solve in a child process (spawned once, restarted after it dies)."""

    def __init__(self):
        self._proc = None
        self._conn = None
        self._newer = None  # a byte shared with the child: a newer frame waits
        self._lock = asyncio.Lock()
        self._pending: asyncio.Future | None = None  # a submitted solve's answer, not read yet
        self.restarts = 0  # processes lost and replaced
        self.cpu_ms = 0.0  # CPU time the child spent on the last request
        self.stopped = False  # the last solve yielded to a newer frame

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None else None

    def _start(self) -> None:
        ctx = multiprocessing.get_context("spawn")  # no fork of a process with an event loop and threads
        parent, child = ctx.Pipe()
        self._newer = ctx.RawValue("b", 0)
        self._proc = ctx.Process(target=_serve, args=(child, self._newer), daemon=True, name="kinetre-solve")
        self._proc.start()
        child.close()
        self._conn = parent

    async def _call(self, *request):
        async with self._lock:
            while self._pending is not None:  # a submitted solve's answer comes first
                await asyncio.wait([self._pending])
            if self._proc is None or not self._proc.is_alive():
                if self._proc is not None:
                    self.restarts += 1
                await asyncio.to_thread(self._start)
            try:
                self._conn.send(request)
                await self._readable()
                status, value, cpu, stopped = self._conn.recv()
            except (EOFError, OSError, BrokenPipeError):
                self._lost()
                raise SolverLost("the solve process stopped; possess again") from None
        self.cpu_ms, self.stopped = 1000 * cpu, stopped
        if status == "error":
            raise value
        return value

    async def _readable(self) -> None:
        """Wait for the reply on the event loop itself: a thread blocked in recv() would then need the GIL
        from the busy serving thread, adding up to a switch interval (`sys.getswitchinterval`) per hop to every
        solve."""
        loop = asyncio.get_running_loop()
        ready = loop.create_future()
        fd = self._conn.fileno()
        loop.add_reader(fd, lambda: ready.done() or ready.set_result(None))  # also wakes on EOF (child died)
        try:
            await ready
        finally:
            _unwatch(loop, fd)

    async def start(self) -> int:
        """Spawn the process now (instead of at the first possession); returns its pid."""
        return await self._call("ping")

    async def attach(self, graph, skeletons, settings: SolverSettings = SolverSettings(),
                     **reach) -> list[np.ndarray]:
        """`kinetre.attach` in the child; `reach`: its reach and bone_radius, when not a person's."""
        return await self._call("attach", graph, skeletons, settings, reach)

    def newer_frame(self) -> None:
        """A newer frame waits: a long solve yields to it (see `yielding`)."""
        if self._newer is not None:
            self._newer.value = 1

    async def solve(self, skeletons, overdue: bool = False) -> GraphPose:
        """See `InlineSolver.solve`."""
        if self._newer is not None:
            self._newer.value = int(overdue)  # else frames that arrive from now on are newer than these
        return await self._call("solve", skeletons)

    def submit(self, skeletons, overdue: bool, ended: Ended) -> None:
        """`solve`, with the request written now and `ended` called in the event loop's callback that finds
        the answer readable (no task wakes on either side). While the process is not up, or another request
        is under way, it goes through `solve`."""
        if self._proc is None or self._lock.locked() or self._pending is not None:
            submitted(self.solve(skeletons, overdue), ended)
            return
        loop = asyncio.get_running_loop()
        self._newer.value = int(overdue)
        try:
            self._conn.send(("solve", skeletons))
        except (OSError, BrokenPipeError):
            self._lost()
            loop.call_soon(ended, SolverLost("the solve process stopped; possess again"))
            return
        fd = self._conn.fileno()
        self._pending = loop.create_future()

        def answered() -> None:  # also on EOF: the child died
            _unwatch(loop, fd)
            pending, self._pending = self._pending, None
            pending.set_result(None)
            try:
                status, value, cpu, stopped = self._conn.recv()
            except (EOFError, OSError):
                self._lost()
                ended(SolverLost("the solve process stopped; possess again"))
                return
            self.cpu_ms, self.stopped = 1000 * cpu, stopped
            ended(value)  # the pose, or the error the child reported
        loop.add_reader(fd, answered)

    def _lost(self) -> None:
        self._proc = None
        self.restarts += 1  # the next call starts a new process

    def detach(self) -> None:
        pass  # the child's rig is replaced at the next attach

    def close(self) -> None:
        if self._pending is not None:  # a solve's answer will not be read
            try:
                asyncio.get_running_loop().remove_reader(self._conn.fileno())
            except (RuntimeError, OSError, ValueError):
                pass
            self._pending.set_result(None)
            self._pending = None
        if self._proc is not None:
            try:
                self._conn.close()
            except OSError:
                pass
            self._proc.join(2)
            if self._proc.is_alive():
                self._proc.kill()
                self._proc.join(2)
            self._proc = None
