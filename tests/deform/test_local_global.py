"""The local/global solver (`method="local_global"`): exact on rigid motions, its fixed point is the true
minimum, E never increases, and it follows the exact Gauss-Newton solve on the shared walk."""

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kinetre
from kinetre.deform import krylov
from kinetre.deform.coordinate_split import CoordinateSplit
from kinetre.deform.energy import EnergyWeights
from kinetre.deform.gradient import energy_gradient
from kinetre.deform.local_global import LocalGlobalSettings, _nonlinear_gradient
from kinetre.deform.normal_equations import NormalEquations
from kinetre.deform.solver import GaussNewton, SolverSettings

from .test_solver import _bend, identity_x, node_constraints

LOCAL_GLOBAL = SolverSettings(method="local_global")
# the reference run to convergence: at its default stop (a step gaining < 1e-3 of E) the exact solve
# ends ~1e-3 above the minimum, and local/global below it (median −1.0e-3 on the two-skeleton walk)
TIGHT = 1e-5


@pytest.fixture(scope="module")
def armadillo(data_dir):
    m = kinetre.load_mesh(data_dir / "meshes" / "armadillo.obj")
    return m, kinetre.build_graph(m, nodes=128, seed=0)


def _pose(x):
    return kinetre.GraphPose(x[:, :9].reshape(-1, 3, 3), x[:, 9:])


@pytest.mark.parametrize("angles", [(20, 30, -10), (0, 90, 0)])
def test_rigid_motion_of_all_constraints_is_reproduced_exactly(armadillo, angles):
    """From rest, by local/global iterations alone (no hand-over to Gauss-Newton). Larger turns from rest
    can end in another local minimum of E_rot; `solve` gives such jumps a rigid start and twice the steps."""
    m, g = armadillo
    cons = node_constraints(g, np.arange(0, g.node_count, 5))
    rot = Rotation.from_euler("xyz", angles, degrees=True).as_matrix()
    shift = np.array([0.3, -0.2, 0.5])
    ne = NormalEquations.build(g.nodes, g.edges, g.edges[g.bridges], cons, EnergyWeights())
    settings = dataclasses.replace(LOCAL_GLOBAL, local_global=LocalGlobalSettings(
        max_iterations=300, gain_tolerance=1e-12, then_gauss_newton=0))
    rep = GaussNewton(ne, settings)._solve_local_global(identity_x(g.node_count), cons.points @ rot.T + shift,
                                                         np.ones(len(cons)))
    assert rep.cg_iterations == 0 and np.all(np.diff(rep.energies) < 0)
    mats = _pose(rep.x).node_matrices(g.nodes)
    assert np.abs(mats[:, :3, :3] - rot).max() < 1e-6
    assert np.abs(mats[:, :3, 3] - shift).max() < 1e-6


def test_fixed_point_is_the_exact_gauss_newton_minimum(armadillo):
    """Run to convergence without handing over to Gauss-Newton: the local/global iteration itself ends at
    E's minimum (an ARAP-style alternation would stop at a different pose), monotonically."""
    m, g = armadillo
    cons, targets = _bend(g)
    ne = NormalEquations.build(g.nodes, g.edges, g.edges[g.bridges], cons, EnergyWeights())
    exact = GaussNewton(ne, SolverSettings(method="exact", max_iterations=200, relative_tolerance=1e-10)).solve(
        identity_x(g.node_count), targets, np.ones(len(cons)))
    settings = dataclasses.replace(LOCAL_GLOBAL, local_global=LocalGlobalSettings(
        max_iterations=2000, gain_tolerance=1e-11, then_gauss_newton=0))
    rep = GaussNewton(ne, settings)._solve_local_global(identity_x(g.node_count), targets, np.ones(len(cons)))
    assert rep.cg_iterations == 0 and rep.factorisations <= 1  # no Gauss-Newton step was needed
    assert np.all(np.diff(rep.energies) < 0)
    assert abs(rep.energy - exact.energy) <= 1e-6 * exact.energy
    moved = kinetre.skin(m, g, _pose(rep.x)) - kinetre.skin(m, g, _pose(exact.x))
    assert np.abs(moved).max() < 1e-3 * m.diagonal


def test_gradient_after_the_global_step_needs_only_the_node_terms(armadillo):
    """∇E(y − α S g) = ∇E(y) − α (g − σ S g) − ∇F(y) + ∇F(y − α S g), F the node-local terms: the identity
    the iteration uses instead of a pass over all terms."""
    m, g = armadillo
    cons, targets = _bend(g)
    w = EnergyWeights(rot=1.3, reg=7.0, con=90.0, rig=2.0)
    bridges = g.edges[np.arange(0, len(g.edges), 9)]  # many bridges, to exercise E_rig's rotation part
    ne = NormalEquations.build(g.nodes, g.edges, bridges, cons, w)
    active = np.ones(len(cons))
    active[::3] = 0.0
    _, fac, _ = CoordinateSplit(ne).for_active(active)
    n = g.node_count
    x = identity_x(n) + 0.2 * np.random.default_rng(0).standard_normal((n, 12))

    def gradient(x):
        out = np.empty(12 * n)
        energy_gradient(np.ascontiguousarray(x), ne.g, ne.edges, cons.nodes, cons.weights, cons.points, targets,
                        active, ne.bridges, w.rot, w.reg, w.con, w.rig, out, True)
        return out

    g0 = gradient(x)
    s = np.empty(12 * n)
    krylov._coordinate_solve(fac, g0, s, np.empty(12 * n))
    y = krylov.to_coordinate_layout(x)
    f0, f1 = np.empty(12 * n), np.empty(12 * n)
    _nonlinear_gradient(y, ne.bridges, w.rot, w.rig, f0)
    for alpha in (1.0, 0.3):
        _nonlinear_gradient(y - alpha * s, ne.bridges, w.rot, w.rig, f1)
        want = gradient(x - alpha * krylov.from_coordinate_layout(s))
        got = g0 - alpha * (g0 - fac[5] * s) - f0 + f1
        assert np.abs(got - want).max() < 1e-10 * np.abs(want).max()


def _follows_exact(data_dir, frames_to, subset=None, skeletons=1):
    """Per frame (E of local/global) / (E of exact Gauss-Newton, converged) − 1 on the walk, each
    warm-starting from its own poses; asserts E never increases within a frame."""
    from kinetre.motion.bvh import load_bvh
    from synthetic import capsule_body
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, frames_to, 4)]
    second = [f.transformed(translation=(0.03, 0.0, 0.02)) for f in frames[5:] + frames[:5]]
    g = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=128, seed=0)
    binds = [frames[0], second[0]][:skeletons]
    exact = kinetre.attach(g, binds, subset=subset, settings=SolverSettings(method="exact", relative_tolerance=TIGHT))
    rig = kinetre.attach(g, binds, subset=subset, settings=LOCAL_GLOBAL)
    rel = []
    for f, f2 in zip(frames[1:], second[1:]):
        cur = [f, f2][:skeletons]
        e_exact = exact.solve(cur).energy
        rig.solve(cur)
        rep = rig.last_report
        assert np.all(np.diff(rep.energies) < 0)
        assert np.all(np.isfinite(rep.x))
        rel.append(rep.energy / e_exact - 1)
    return np.array(rel)


def test_follows_the_exact_solve_on_the_walk_with_two_skeletons(data_dir):
    rel = _follows_exact(data_dir, 120, skeletons=2)
    assert np.median(np.abs(rel)) < 1e-3 and np.abs(rel).max() < 1e-2, rel


def test_follows_the_exact_solve_when_one_arm_possesses_the_body(data_dir):
    """Most of the graph is held only by E_reg/E_rot: rotations must travel through the graph."""
    rel = _follows_exact(data_dir, 160, subset="right arm")
    assert np.median(np.abs(rel)) < 1e-3 and np.abs(rel).max() < 1e-2, rel


def test_animate_solver_option_runs_end_to_end(capsys, tmp_path, data_dir):
    """`kinetre animate --solver local_global` ends at the default solver's energies."""
    import re

    from kinetre.cli import main
    median = {}
    for solver in ("local_global", "pcg"):
        code = main(["animate", str(data_dir / "meshes" / "spot.obj"), "--motion",
                     str(data_dir / "bvh" / "cmu_12_01_walk.bvh"), "--nodes", "48", "--max-frames", "12", "--fit",
                     "-o", str(tmp_path / f"{solver}.glb"), "--solver", solver])
        out, err = capsys.readouterr()
        assert code == 0, err
        assert "solved 12 frames" in out
        median[solver] = float(re.search(r"median energy ([0-9.e+-]+)", out).group(1))
    assert median["local_global"] == pytest.approx(median["pcg"], rel=2e-2)
