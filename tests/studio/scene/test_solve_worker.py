"""The solve in its own process: the same poses as an in-process rig, and a killed worker is
replaced with the scene re-attaching everybody at their current pose."""
import asyncio
import os
import signal

import numpy as np
import pytest

from kinetre.studio.channels import Frame, Hub
from kinetre.studio.meshes import data_path, prepare_mesh
from kinetre.studio.protocol import SkeletonFrame
from kinetre.studio.scene import Scene
from kinetre.studio.scene.solve_worker import InlineSolver, SolverLost, SolveWorker


@pytest.fixture(scope="module")
def spot64():
    return prepare_mesh(str(data_path("spot.obj")), 64)


def feed(scene, k, skeleton):
    scene.receive(Frame("kinetre.skeleton.u", k, float(k), b"", SkeletonFrame(k, float(k), skeleton)))


async def drive(scene, walk, frames=(10, 20, 30)):
    feed(scene, 1, walk[0])
    scene.fit("u")
    await scene.possess("u")
    poses = [await scene.solve_once()]
    for i, k in enumerate(frames):
        feed(scene, i + 2, walk[k])
        poses.append(await scene.solve_once())
    return [p.node_matrices(scene.meshes.first.graph.nodes) for p in poses]


def test_worker_solves_like_the_inline_rig(spot64, walk):
    mesh, graph = spot64

    async def run(solver):
        try:
            return await drive(Scene(Hub(), mesh, graph, solver=solver), walk)
        finally:
            solver.close()

    inline = asyncio.run(run(InlineSolver()))
    worker = asyncio.run(run(SolveWorker()))
    assert np.abs(inline[-1] - np.eye(4)).max() > 0.01  # the frames do deform the mesh
    for a, b in zip(inline, worker):
        np.testing.assert_allclose(b, a, atol=1e-9)


@pytest.mark.slow
def test_a_killed_worker_is_replaced_and_the_scene_reattaches(spot64, walk):
    mesh, graph = spot64

    async def go():
        worker = SolveWorker()
        scene = Scene(Hub(), mesh, graph, solver=worker)
        try:
            await drive(scene, walk, frames=(10,))
            first = worker.pid
            os.kill(first, signal.SIGKILL)
            feed(scene, 5, walk[20])
            with pytest.raises(SolverLost):
                await scene.solve_once()
            assert scene.meshes.first.rig is None  # nobody is driven until the new worker has the rig
            for _ in range(1200):  # the scene re-attaches in the background (a new worker may compile first)
                await asyncio.sleep(0.05)
                if scene.meshes.first.rig is not None:
                    break
            feed(scene, 6, walk[30])
            pose = await scene.solve_once()
            return first, worker.pid, worker.restarts, pose, scene.users["u"].bind is not None
        finally:
            worker.close()

    first, second, restarts, pose, possessing = asyncio.run(go())
    assert second != first and restarts == 1 and possessing
    assert pose is not None and np.isfinite(pose.rotations).all()


def test_worker_under_uvloop_keeps_its_pipe_blocking(spot64, walk):
    """The studio serves on uvloop (as uvicorn picks it), whose add_reader leaves the pipe non-blocking: a
    reply written in two parts (a pose over 16 kB: header, then body) read in between would then fail as a lost
    worker under load. The pipe must be blocking again after each wait, and the poses those of the inline rig."""
    import uvloop
    mesh, graph = spot64

    async def run(solver):
        try:
            poses = await drive(Scene(Hub(), mesh, graph, solver=solver), walk)
            return poses, solver
        finally:
            blocking = os.get_blocking(solver._conn.fileno()) if isinstance(solver, SolveWorker) else True
            solver.close()
            assert blocking, "the solve worker's pipe was left non-blocking"

    inline, _ = asyncio.run(run(InlineSolver()))
    worker, _ = uvloop.run(run(SolveWorker()))
    for a, b in zip(inline, worker):
        np.testing.assert_allclose(b, a, atol=1e-9)
