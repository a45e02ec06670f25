"""The solve worker's process side reads the scene's shared "newer frame" byte inside the PCG loop: a solve
with it set (and its CPU share spent) yields after one accepted step and says so in its reply; the same
frame with it clear runs to convergence."""
import asyncio
import multiprocessing
import threading

import numpy as np
import pytest

from kinetre.deform.solver import SolverSettings
from kinetre.studio.scene import solve_worker
from kinetre.studio.meshes import data_path, prepare_mesh
from kinetre.studio.protocol import SkeletonFrame
from kinetre.studio.placement import Placement


@pytest.fixture(scope="module")
def spot64():
    return prepare_mesh(str(data_path("spot.obj")), 64)


def serve(newer, requests):
    """`_serve` in a thread of this process, over a real pipe and a real shared byte: the replies."""
    parent, child = multiprocessing.Pipe()
    thread = threading.Thread(target=solve_worker._serve, args=(child, newer), daemon=True)
    thread.start()
    replies = []
    for request, flag in requests:
        newer.value = flag
        parent.send(request)
        replies.append(parent.recv())
    parent.close()
    thread.join(30)
    assert not thread.is_alive()
    return replies


def test_the_worker_yields_inside_the_pcg_loop_when_the_shared_byte_is_set(spot64, walk, monkeypatch):
    monkeypatch.setattr(solve_worker, "warm_up", lambda: None)
    monkeypatch.setattr(solve_worker, "freeze_heap", lambda: None)
    monkeypatch.setattr(solve_worker, "YIELD_AFTER_S", -1.0)  # the frame's CPU share is spent at once
    mesh, graph = spot64
    place = Placement.fitted(walk[0], mesh)
    skeletons = [place.to_local(walk[k]) for k in (0, 4, 12)]
    attach = ("attach", graph, skeletons[0], SolverSettings(), {})
    runs = {}
    for flag in (0, 1):
        newer = multiprocessing.get_context("spawn").RawValue("b", 0)
        runs[flag] = serve(newer, [(attach, 0), (("solve", skeletons[1]), 0), (("solve", skeletons[2]), flag)])
    free, cut = runs[0][-1], runs[1][-1]
    assert free[0] == cut[0] == "ok"
    assert not free[3] and free[1].iterations >= 2  # uncut, the frame takes several steps
    assert cut[3] and cut[1].iterations == 1  # yielded after its first step
    assert free[1].energy < cut[1].energy  # not converged
    np.testing.assert_array_equal(runs[0][1][1].rotations, runs[1][1][1].rotations)  # the same until then


class StubSolver:
    """Poses 1, 2, … (node translations), each solve taking a few loop turns; records what was published when
    each solve was asked for and whether it was asked to yield."""

    def __init__(self, graph, published):
        self.graph, self.published, self.calls, self.cpu_ms, self.yielded = graph, published, [], 0.0, 0

    async def attach(self, graph, skeletons, settings=None):
        return [np.arange(3)]

    def newer_frame(self):
        self.yielded += 1

    async def solve(self, skeleton, overdue=False):
        from kinetre.deform.pose import GraphPose
        self.calls.append(len(self.published))
        self.yielded += overdue  # asked with the request when the frame was overdue already
        await asyncio.sleep(0.01)
        pose = GraphPose.identity(self.graph.node_count)
        pose.translations[:] = len(self.calls)
        return pose

    def submit(self, skeleton, overdue, ended):
        solve_worker.submitted(self.solve(skeleton, overdue), ended)


def test_a_solved_pose_goes_out_as_its_solve_ends_even_with_a_newer_frame_waiting(spot64, walk):
    """Every solved pose is published once, in order, and recorded, as soon as its solve ends: one whose solve
    ended with a newer frame waiting is out before the next solve is asked for. `late` asks a solve whose
    frame is that old to yield."""
    from kinetre.studio.channels import Frame, Hub
    from kinetre.studio.scene import Scene
    from kinetre.studio.subjects import TRANSFORMS
    from kinetre.wire.transforms import unpack_transforms
    mesh, graph = spot64
    hub = Hub()
    published = []
    hub.subscribe(TRANSFORMS).direct = lambda frame: published.append(frame.data) or True

    async def go():
        scene = Scene(hub, mesh, graph, solver=StubSolver(graph, published))
        solver = scene.meshes.first.solver

        def feed(k):
            scene.receive(Frame("kinetre.skeleton.u", k, float(k), b"", SkeletonFrame(k, float(k), walk[k])))
        feed(1)
        await scene.possess("u")
        start = len(published)
        await scene.solve_once()  # nothing newer: out at once
        after_first = len(published)
        feed(2)
        task = asyncio.get_running_loop().create_task(scene.solve_once())
        await asyncio.sleep(0.002)
        feed(3)  # arrives during the second solve
        await task
        after_second = len(published)
        assert solver.yielded == 2  # frames 2 and 3 arrived (Scene.receive); no timer without `late`
        await scene.solve_once(late=0.0)  # the third, asked to yield at once
        assert solver.yielded == 3
        return start, after_first, after_second, solver

    start, after_first, after_second, solver = asyncio.run(go())
    assert after_first == start + 1
    assert after_second == after_first + 1  # out at once, though a newer frame waited
    assert solver.calls[-1] == after_second  # …before the third solve was asked for
    assert len(published) == after_second + 1  # then the third
    moved = [float(unpack_transforms(block)[4][0, 0, 3]) for block in published[start:]]  # node 0's t_x
    assert moved == [1.0, 2.0, 3.0]


def test_a_pose_solved_while_a_newer_frame_waits_is_in_the_take_when_recording_stops(spot64, walk):
    """Stop recording right after a solve that ended with a newer frame waiting: the take has its pose."""
    from kinetre.studio.channels import Frame, Hub
    from kinetre.studio.scene import Scene
    mesh, graph = spot64

    async def go():
        scene = Scene(Hub(), mesh, graph, solver=StubSolver(graph, []))
        scene.receive(Frame("kinetre.skeleton.u", 1, 1.0, b"", SkeletonFrame(1, 1.0, walk[1])))
        await scene.possess("u")
        scene.start_recording()
        await scene.solve_once()  # out at once: recorded
        scene.receive(Frame("kinetre.skeleton.u", 2, 2.0, b"", SkeletonFrame(2, 2.0, walk[2])))
        task = asyncio.get_running_loop().create_task(scene.solve_once())
        await asyncio.sleep(0.002)
        scene.receive(Frame("kinetre.skeleton.u", 3, 3.0, b"", SkeletonFrame(3, 3.0, walk[3])))  # during the second solve
        await task
        return scene.stop_recordings()[scene.meshes.first.id]  # the second solve's pose is in it already

    take = asyncio.run(go())
    assert [float(frame.pose.translations[0, 0]) for frame in take] == [1.0, 2.0]


def test_a_live_solve_cut_short_with_no_newer_frame_goes_on_until_the_frame_is_solved(spot64, walk, monkeypatch):
    """On a machine too busy for the live budget a solve yields after its first step (its frame is late at
    once, its CPU share spent) and its pose goes out. With no newer frame to go on with, the live loop solves
    the same frame on from there, not cut for lateness again: its last pose, under the frame's time, is the
    uncut solve's."""
    from kinetre.studio.channels import Frame, Hub
    from kinetre.studio.scene import Scene, solve_loop
    from kinetre.studio.subjects import TRANSFORMS
    from kinetre.wire.transforms import unpack_transforms
    mesh, graph = spot64

    def frame(k, skeleton):
        return Frame("kinetre.skeleton.u", k, 1000.0 * k, b"", SkeletonFrame(k, 1000.0 * k, skeleton))

    async def uncut():
        scene = Scene(Hub(), mesh, graph)
        scene.receive(frame(1, walk[0]))
        scene.fit("u")
        await scene.possess("u")
        await scene.solve_once()
        scene.receive(frame(2, walk[10]))
        await scene.solve_once()
        return scene.meshes.first.pose.node_matrices(graph.nodes)

    expected = asyncio.run(uncut())
    monkeypatch.setattr(solve_loop, "LATE_S", 0.0)
    monkeypatch.setattr(solve_worker, "YIELD_AFTER_S", 0.0)
    hub = Hub()
    published = []
    hub.subscribe(TRANSFORMS).direct = lambda f: published.append(f.data) or True

    async def live():
        scene = Scene(hub, mesh, graph)
        scene.receive(frame(1, walk[0]))
        scene.fit("u")
        await scene.possess("u")
        await scene.solve_once()
        m = scene.meshes.first
        running = asyncio.get_running_loop().create_task(scene.run())
        start = len(published)
        scene.receive(frame(2, walk[10]))
        for _ in range(3000):  # until the loop waits for a frame again, its last solve not cut short
            await asyncio.sleep(0.01)
            if len(published) > start and m.solving is None and not m.dirty.is_set() and not m.solver.stopped:
                break
        running.cancel()
        return published[start:], m.stopped

    blocks, stopped = asyncio.run(live())
    assert stopped == 1 and len(blocks) == 2  # cut short once, then solved on to the end: both poses went out
    assert [unpack_transforms(b)[2] for b in blocks] == [2000.0, 2000.0]  # under the frame's own time
    first, last = (unpack_transforms(b)[4] for b in blocks)
    assert np.abs(first - expected).max() > 1e-3  # the first pose out was not the solve's end
    np.testing.assert_allclose(last, expected, atol=2e-4 * max(1.0, np.abs(expected - np.eye(4)).max()))


def test_a_cut_short_solve_is_resumed_only_once_its_users_frames_are_overdue(spot64, walk):
    """While a user's frames keep coming, the next one goes on from a cut-short pose; the same frame is solved
    on uncut only when no newer frame came within the user's frame period (they stopped or paused)."""
    from kinetre.studio.channels import Frame, Hub
    from kinetre.studio.scene import Scene
    mesh, graph = spot64

    def frame(k, skeleton):
        return Frame("kinetre.skeleton.u", k, 1000.0 * k, b"", SkeletonFrame(k, 1000.0 * k, skeleton))

    async def run(period):
        scene = Scene(Hub(), mesh, graph)
        scene.receive(frame(1, walk[0]))
        scene.fit("u")
        await scene.possess("u")
        m = scene.meshes.first
        user = scene.users["u"]
        user.period = period
        m.dirty.clear()
        scene.solves.resume_when_quiet(m)
        await asyncio.sleep(0.2)
        quiet = m.dirty.is_set()
        m.dirty.clear()
        scene.solves.resume_when_quiet(m)
        scene.receive(frame(2, walk[1]))  # a newer frame in time: it wakes the loop itself
        m.dirty.clear()
        await asyncio.sleep(0.2)
        return quiet, m.dirty.is_set()

    assert asyncio.run(run(0.01)) == (True, False)  # overdue after 15 ms: resumed; a newer frame: not
    assert asyncio.run(run(30.0)) == (False, False)  # a 30 s period: the next frame is not overdue yet


class FailingOnceSolver(StubSolver):
    """`StubSolver`, but its first live solve fails (a bug, or a bad frame); then it solves as before."""

    async def solve(self, skeleton, overdue=False):
        if not self.calls:
            self.calls.append(len(self.published))
            raise RuntimeError("boom")
        return await super().solve(skeleton, overdue)


def test_a_live_solve_that_fails_is_reported_and_the_next_frame_is_solved(spot64, walk):
    """One failed solve must not stop the scene: the state's error line names it, and the user's next frame is
    solved and published."""
    from kinetre.studio.channels import Frame, Hub
    from kinetre.studio.scene import Scene
    from kinetre.studio.subjects import TRANSFORMS
    mesh, graph = spot64
    hub = Hub()
    published = []
    hub.subscribe(TRANSFORMS).direct = lambda frame: published.append(frame.data) or True

    def feed(scene, k):
        scene.receive(Frame("kinetre.skeleton.u", k, 1000.0 * k, b"", SkeletonFrame(k, 1000.0 * k, walk[k])))

    async def go():
        scene = Scene(hub, mesh, graph, solver=FailingOnceSolver(graph, published))
        feed(scene, 1)
        await scene.possess("u")
        start = len(published)
        running = asyncio.get_running_loop().create_task(scene.run())
        await asyncio.sleep(0.05)  # the possessed frame's solve, which fails
        failed = scene.last_error, len(published) - start
        feed(scene, 2)
        await asyncio.sleep(0.05)
        running.cancel()
        return failed, len(published) - start, scene.meshes.first.solving

    (error, after_failure), after_next, solving = asyncio.run(go())
    assert "RuntimeError: boom" in error and after_failure == 0
    assert after_next == 1 and solving is None
