"""A jump frame's rigid start (deform/rigid_start.py): the best rigid motion of the constraint
carriers onto their new targets, offered to the solver as a start kept only when E is lower."""
import dataclasses

import numpy as np
import pytest

import kinetre
from kinetre.deform.solver import SolverSettings
from kinetre.deform.rigid_start import best_rotation, carriers, rigid_start
from kinetre.skeleton.models import Skeleton


def rotation_about(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_best_rotation_recovers_a_rigid_motion_and_ignores_zero_weights():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(12, 3))
    R = rotation_about([1, 2, -0.5], 2.5)  # beyond 90°: no small-angle shortcut
    dst = src @ R.T + [3.0, -1.0, 0.5]
    w = np.ones(12)
    dst[:3] += 100.0  # garbage on rows whose weight is zero
    w[:3] = 0.0
    rot, c, c_new = best_rotation(src, dst, w)
    np.testing.assert_allclose(rot, R, atol=1e-12)
    np.testing.assert_allclose((src[3:] - c) @ rot.T + c_new, dst[3:], atol=1e-12)
    assert np.linalg.det(best_rotation(src, -src, np.ones(12))[0]) == pytest.approx(1.0)  # never a reflection
    assert best_rotation(src, dst, np.zeros(12)) is None


@pytest.fixture(scope="module")
def walk(data_dir):
    from kinetre.motion.bvh import load_bvh
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    return [take.frame(i) for i in range(0, 120, 4)]


def test_constraints_moved_rigidly_are_met_by_the_rigid_start_alone(walk):
    from synthetic import capsule_body
    graph = kinetre.build_graph(capsule_body(walk[0], radius=0.06), nodes=128, seed=0)
    rig = kinetre.attach(graph, walk[0])
    for f in walk[1:8]:
        rig.solve(f)
    solver = rig.solver
    settled = walk[7]
    for _ in range(6):  # converge on the last frame
        rig.solve(settled)
    x, e_settled = rig._x.copy(), rig.last_report.energy
    R, shift = rotation_about([0.2, 1.0, 0.1], 2.0), np.array([1.5, 0.0, -2.0])
    moved = settled.transformed(1.0, R, shift)  # its bone frames turned with it
    q, ok = rig.targets(moved)
    start = rigid_start(x, solver.system.g, solver.system.constraints, q, ok.astype(float))
    # every node composed with the motion: A' = R A, and the carriers land where R moved the old targets
    np.testing.assert_allclose(start[:, :9].reshape(-1, 3, 3), R @ x[:, :9].reshape(-1, 3, 3), atol=1e-4)
    np.testing.assert_allclose(carriers(start, solver.system.g, solver.system.constraints),
                               carriers(x, solver.system.g, solver.system.constraints) @ R.T + shift, atol=1e-4)
    assert solver.energy(start, q, ok.astype(float)) == pytest.approx(e_settled, rel=1e-6)
    # the solve: a 3 m, 115° teleport, yet no exact jump solve, and E stays at the settled pose's
    e_teleport = solver.energy(x, q, ok.astype(float))
    assert e_teleport > 100 * e_settled  # far beyond the jump threshold (10×)
    rig.solve(moved)
    report = rig.last_report
    assert report.energies[0] == pytest.approx(e_settled, rel=1e-6)  # the start is the rigid one
    assert report.factorisations == 0 and report.iterations <= 2  # already converged: no jump solve
    assert report.energy <= report.energies[0]


@pytest.mark.slow
def test_a_teleport_mid_walk_rejoins_the_exact_solve_and_e_never_rises(data_dir):
    from kinetre.motion.bvh import load_bvh
    from synthetic import capsule_body
    # joint positions only (as a camera gives them): the bounds below were set on that path
    take = dataclasses.replace(load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh"), bone_frames=None)
    frames = [take.frame(i) for i in range(0, 80, 4)]
    R = rotation_about([0, 1, 0], 1.2)  # found elsewhere, facing another way
    moved = [take.frame(i).transformed(1.0, R, [0.4, 0.0, 0.1]) for i in range(240, 400, 4)]
    graph = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=128, seed=0)

    def run(settings):
        rig = kinetre.attach(graph, frames[0], settings=settings)
        for f in frames[1:]:
            rig.solve(f)
        out = []
        for f in moved:
            e_start = rig.solver.energy(rig._x, *(lambda q, ok: (q, ok.astype(float)))(*rig.targets(f)))
            rig.solve(f)
            out.append((e_start, rig.last_report))
        return out

    fast = run(SolverSettings())
    exact = run(SolverSettings(method="exact"))
    for e_start, r in fast:
        assert r.energies[0] <= e_start * (1 + 1e-12) and np.all(np.diff(r.energies) < 0)  # E never rises within a frame
    rel = np.array([f.energy for _, f in fast]) / [e.energy for _, e in exact] - 1
    # the jump frame lands on the exact solve's energy; after it the fast path's usual walking drift
    # (its steps stop at a relative decrease of 1e-3 per frame) and no worse
    assert abs(rel[0]) < 1e-3 and np.median(np.abs(rel)) < 1e-3 and np.abs(rel).max() < 2e-2, rel


def test_one_of_two_users_teleporting_is_a_jump_whose_pcg_steps_match_exact_ones(data_dir):
    """Two users drive a leg each; from frame 20 the right leg's user is 20 frames (2.7 s, ~3 m) behind:
    no rigid motion fits, the frame stays a jump. Its PCG steps from the rigid start end where the exact
    steps do (jump_steps="exact"), and near the all-exact solve, at a fraction of the cost."""
    from kinetre.motion.bvh import load_bvh
    from kinetre.skeleton.subsets import subset_mask
    from synthetic import capsule_body
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 140, 4)]

    def leg(f, side):
        return Skeleton(f.model, f.positions, f.tracked & subset_mask(f.model, side + " leg"), f.bone_frames)

    graph = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=128, seed=0)

    def run(settings):
        rig = kinetre.attach(graph, [leg(frames[0], "left"), leg(frames[0], "right")], settings=settings)
        out = []
        for k, f in enumerate(frames[1:], 1):
            behind = frames[k - 20] if k >= 20 else f
            q, ok = rig.targets([leg(f, "left"), leg(behind, "right")])
            e_start = rig.solver.energy(rig._x, q, ok.astype(float))
            rig.solve([leg(f, "left"), leg(behind, "right")])
            out.append((e_start, rig.last_report))
        return out

    pcg = run(SolverSettings())
    by_exact_steps = run(SolverSettings(jump_steps="exact"))
    exact = run(SolverSettings(method="exact"))
    jump = 19  # frame 20
    assert by_exact_steps[jump][1].cg_iterations == 0  # a jump even from the rigid start: exact steps there
    assert pcg[jump][1].cg_iterations > 0 and pcg[jump][1].factorisations <= 1
    assert pcg[jump][1].energy < 0.1 * pcg[jump][0]
    for e_start, r in pcg:
        assert r.energies[0] <= e_start * (1 + 1e-12) and np.all(np.diff(r.energies) < 0)  # E never rises within a frame
    e = np.array([r.energy for _, r in pcg[jump:]])
    e_exact_steps = np.array([r.energy for _, r in by_exact_steps[jump:]])
    np.testing.assert_allclose(e, e_exact_steps, rtol=2e-3)
    # and no higher than them by more than 1e-3 (the coarse space can take the jump frame lower still)
    rest = [0, *range(2, len(e))]
    assert np.all(e[rest] <= e_exact_steps[rest] * (1 + 1e-3)), e[rest] / e_exact_steps[rest] - 1
    np.testing.assert_allclose(e, [r.energy for _, r in exact[jump:]], rtol=2e-2)
