"""A jump frame's exact solve cut short by `stop` (a live solve with a newer frame waiting) goes on
over the next frames: each frame lowers E, the catch-up stays exact within the jump's budget, and the poses
rejoin those of the uninterrupted solve."""
import numpy as np
import pytest

import kinetre
from kinetre.deform.solver import SolverSettings
from kinetre.skeleton.models import Skeleton


@pytest.fixture(scope="module")
def walk_with_teleport(data_dir):
    """The CMU walk at 30 Hz for 20 frames, then the same walk from further on, 40 cm to the side (a
    tracker that lost the user and found them elsewhere), 40 more frames."""
    from kinetre.motion.bvh import load_bvh
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 80, 4)]
    moved = [take.frame(i) for i in range(240, 400, 4)]
    moved = [Skeleton(f.model, f.positions + [0.4, 0.0, 0.1], f.tracked) for f in moved]
    return frames, moved


@pytest.fixture(autouse=True)
def no_rigid_start(monkeypatch):
    # this walk's teleport is a pure translation, which the rigid start (test_rigid_start.py) turns into a
    # fast-path frame: without it the frame is a jump, whose exact steps (jump_steps="exact") `stop` cuts
    monkeypatch.setattr("kinetre.deform.solver.rigid_start", lambda *args: None)


def run(graph, frames, moved, stop):
    rig = kinetre.attach(graph, frames[0], settings=SolverSettings(jump_steps="exact"))
    for f in frames[1:]:
        rig.solve(f, stop=stop)
    reports = []
    for f in moved:
        rig.solve(f, stop=stop)
        reports.append(rig.last_report)
    return reports


def test_a_stopped_jump_goes_on_exactly_and_rejoins_the_full_solve(walk_with_teleport):
    from synthetic import capsule_body
    frames, moved = walk_with_teleport
    graph = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=128, seed=0)
    full = run(graph, frames, moved, stop=None)
    never = run(graph, frames, moved, stop=lambda: False)
    cut = run(graph, frames, moved, stop=lambda: True)  # a newer frame always waits

    # the jump frame: the uninterrupted solve spends more than one exact step on it
    assert full[0].cg_iterations == 0 and full[0].accepted > 1 and not full[0].stopped
    # a stop that never fires changes nothing
    for a, b in zip(full, never):
        np.testing.assert_array_equal(a.x, b.x)

    # cut short after its first accepted step, E lowered
    assert cut[0].stopped and cut[0].accepted == 1 and cut[0].energies[-1] < cut[0].energies[0]
    catch_up = [r for r in cut if r.cg_iterations == 0 and r.factorisations > 0]
    ends = next(i for i, r in enumerate(cut) if not r.stopped)
    assert all(r.stopped for r in cut[:ends]) and ends > 1  # spread over several frames…
    assert [r.cg_iterations for r in cut[:ends + 1]] == [0] * (ends + 1)  # …all of them exact steps
    assert sum(r.iterations for r in cut[:ends + 1]) <= 2 * 10  # within the jump's own budget
    assert len(catch_up) >= ends
    for r in cut:
        assert np.all(np.diff(r.energies) < 0)  # E never rises within a frame
    # after the catch-up the poses are those of the uninterrupted solve, to its stopping accuracy
    after = slice(ends + 3, None)
    rel = np.array([c.energy for c in cut[after]]) / [f.energy for f in full[after]] - 1
    assert np.median(np.abs(rel)) < 1e-2, rel
