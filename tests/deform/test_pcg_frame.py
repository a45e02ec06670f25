"""A PCG frame in one numba call (`fast/gauss_newton.py`: the constant-velocity guess, the start's energies, the jump
test and the Gauss-Newton loop) gives bit for bit the poses of the same frames solved through the Python path
(the guess made and weighed in numpy, `GaussNewton.solve(guess=...)`), teleports included."""
import numpy as np
import pytest

import kinetre
from kinetre.deform.solver import SolverSettings
from kinetre.motion.bvh import load_bvh
from kinetre.skeleton.models import Skeleton
from synthetic import capsule_body


@pytest.fixture(scope="module")
def walk(data_dir):
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 200, 4)]
    second = [f.transformed(translation=(0.03, 0.0, 0.02)) for f in frames[10:] + frames[:10]]
    graph = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=128, seed=0)
    return graph, frames, second


def python_path(rig, skeletons):
    """`Rig.solve` with the start chosen in Python: the guess 2 x − x_before passed to `GaussNewton.solve`."""
    q, ok = rig.targets(skeletons)
    guess = None if rig._x_before is None else 2.0 * rig._x - rig._x_before
    report = rig.solver.solve(rig._x, q, ok.astype(np.float64), guess)
    rig._x_before, rig._x = rig._x, report.x
    return report


@pytest.mark.parametrize("settings", [SolverSettings(), SolverSettings(preconditioner="two_level")],
                         ids=["default", "two_level"])
def test_one_call_frames_equal_the_python_path(walk, settings, monkeypatch):
    graph, frames, second = walk
    import kinetre.deform.solver as solver
    jumps = []  # the rigid start is tried on jump frames only
    rigid_start = solver.rigid_start
    monkeypatch.setattr(solver, "rigid_start", lambda *args: jumps.append(1) or rigid_start(*args))
    # a teleport 40 cm aside at frame 30: a jump, whose start the numba call hands back to the Python path
    moved = [Skeleton(f.model, f.positions + [0.4, 0.0, 0.1], f.tracked) for f in frames[30:]]
    seq = [[f, s] for f, s in zip(frames[:30] + moved, second)]
    fused, reference = kinetre.attach(graph, seq[0], settings=settings), kinetre.attach(graph, seq[0], settings=settings)
    guessed = 0
    for skeletons in seq[1:]:
        last, before = fused._x.copy(), fused._x_before
        fused.solve(skeletons)
        want = python_path(reference, skeletons)
        got = fused.last_report
        np.testing.assert_array_equal(got.x, want.x)
        assert got.energies == want.energies and got.energy == want.energy
        assert (got.iterations, got.accepted, got.cg_iterations, got.factorisations) == \
            (want.iterations, want.accepted, want.cg_iterations, want.factorisations)
        assert np.all(np.diff(got.energies) < 0)
        if before is not None:  # the guess fitted better than the last pose (it then was the start)
            q, ok = fused.targets(skeletons)
            e_last = fused.solver.energy(last, q, ok.astype(float))
            guessed += fused.solver.energy(2.0 * last - before, q, ok.astype(float)) < e_last
    # the teleport and the second walk's loop-around are jumps, in each of the two rigs
    assert len(jumps) >= 4 and guessed > len(seq) // 2


def test_all_finite_finds_one_bad_entry():
    from kinetre.deform.fast.gauss_newton import all_finite
    x = np.zeros((5, 12))
    x[:, [0, 4, 8]] = 1.0
    assert all_finite(x)
    for bad in (np.nan, np.inf, -np.inf):
        y = x.copy()
        y[3, 10] = bad
        assert not all_finite(y)
