"""The solve worker's process side reads the scene's shared "newer frame" byte inside the PCG loop: a solve
with it set (and its CPU share spent) yields after one accepted step and says so in its reply; the same
frame with it clear runs to convergence."""
import multiprocessing
import threading

import numpy as np
import pytest

from kinetre.deform.solver import SolverSettings
from kinetre.studio import solve_worker
from kinetre.studio.app import data_path, prepare_mesh
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
    sk = walk[0]  # stood where the skeleton stands, scaled to its height (the studio's "fit")
    centre, foot = sk.positions[sk.tracked].mean(axis=0), float(sk.positions[sk.tracked, 1].min())
    place = Placement(sk.height / float(np.ptp(mesh.vertices[:, 1])), (float(centre[0]), foot, float(centre[2])), 0.0)
    skeletons = [place.to_local(walk[k]) for k in (0, 4, 12)]
    attach = ("attach", graph, skeletons[0], SolverSettings())
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
