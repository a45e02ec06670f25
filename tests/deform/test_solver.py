"""Gauss-Newton/LM: exact on rigid motions, monotone energy, tracking loss, rigidity on bridges."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

import kinetre
from kinetre.deform.constraints import PointConstraints
from kinetre.deform.energy import EnergyWeights
from kinetre.deform.normal_equations import NormalEquations
from kinetre.deform.solver import GaussNewton, SolverSettings
from kinetre.mesh.load import mesh_from_trimesh


def identity_x(n):
    x = np.zeros((n, 12))
    x[:, [0, 4, 8]] = 1.0
    return x


def node_constraints(graph, node_ids):
    """Constraints sitting on graph nodes, carried by their 4 nearest nodes (Eq. 2 falloff)."""
    p = graph.nodes[node_ids]
    d = np.linalg.norm(p[:, None] - graph.nodes[None], axis=2)
    order = np.argsort(d, axis=1)[:, :5]
    dd = np.take_along_axis(d, order, axis=1)
    w = 1 - dd[:, :4] / dd[:, 4:5]
    w /= w.sum(axis=1, keepdims=True)
    return PointConstraints(p, order[:, :4].astype(np.int32), w)


def _bend(g):
    top = np.flatnonzero(g.nodes[:, 1] > np.percentile(g.nodes[:, 1], 80))
    bottom = np.flatnonzero(g.nodes[:, 1] < np.percentile(g.nodes[:, 1], 20))
    cons = node_constraints(g, np.concatenate([top, bottom]))
    rot = Rotation.from_euler("z", 40, degrees=True).as_matrix()
    c = g.nodes.mean(axis=0)
    targets = cons.points.copy()
    targets[:len(top)] = (cons.points[:len(top)] - c) @ rot.T + c
    return cons, targets


@pytest.fixture(scope="module")
def armadillo(data_dir):
    m = kinetre.load_mesh(data_dir / "meshes" / "armadillo.obj")
    return m, kinetre.build_graph(m, nodes=128, seed=0)


@pytest.mark.parametrize("angles", [(20, 30, -10), (0, 90, 0), (60, -45, 30)])
def test_rigid_motion_of_all_constraints_is_reproduced_exactly(armadillo, angles):
    m, g = armadillo
    cons = node_constraints(g, np.arange(0, g.node_count, 5))
    rot = Rotation.from_euler("xyz", angles, degrees=True).as_matrix()
    shift = np.array([0.3, -0.2, 0.5])
    ne = NormalEquations.build(g.nodes, g.edges, g.edges[g.bridges], cons, EnergyWeights())
    solver = GaussNewton(ne, SolverSettings(max_iterations=30))
    rep = solver.solve(identity_x(g.node_count), cons.points @ rot.T + shift, np.ones(len(cons)))
    pose = kinetre.GraphPose(rep.x[:, :9].reshape(-1, 3, 3), rep.x[:, 9:])
    mats = pose.node_matrices(g.nodes)
    assert np.abs(mats[:, :3, :3] - rot).max() < 1e-6
    assert np.abs(mats[:, :3, 3] - shift).max() < 1e-6
    v = kinetre.skin(m, g, pose)
    # float32 weights sum to 1 within 1.2e-7: that bounds the vertex error relative to their size
    assert np.abs(v - (m.vertices @ rot.T + shift)).max() < 1e-6 * max(1, np.abs(m.vertices).max())


def test_energy_never_increases_and_converges_within_ten(armadillo):
    m, g = armadillo
    cons, targets = _bend(g)  # the top turns 40° about z around the centre, the bottom stays
    ne = NormalEquations.build(g.nodes, g.edges, g.edges[g.bridges], cons, EnergyWeights())
    rep = GaussNewton(ne).solve(identity_x(g.node_count), targets, np.ones(len(cons)))
    e = np.array(rep.energies)
    assert np.all(np.diff(e) < 0)
    assert rep.iterations <= 10
    assert e[-1] < 0.05 * e[0]
    # converged: another solve from the result takes no step
    rep2 = GaussNewton(ne).solve(rep.x, targets, np.ones(len(cons)))
    assert rep2.energy <= rep.energy and (rep.energy - rep2.energy) <= 1e-3 * rep.energy


def test_inactive_constraints_drop_out(armadillo):
    m, g = armadillo
    cons = node_constraints(g, np.arange(0, g.node_count, 4))
    ne = NormalEquations.build(g.nodes, g.edges, g.edges[g.bridges], cons, EnergyWeights())
    targets = cons.points + [0.1, 0, 0]
    active = np.ones(len(cons))
    targets[::2] = 1e6  # wildly wrong, but inactive
    active[::2] = 0.0
    rep = GaussNewton(ne).solve(identity_x(g.node_count), targets, active)
    moved = np.asarray(rep.x[:, 9:])
    assert np.all(np.isfinite(rep.x)) and np.abs(moved).max() < 1.0
    assert np.allclose(moved.mean(axis=0), [0.1, 0, 0], atol=0.02)


def _chair():
    """A seat and two legs hanging under it by a gap: separate components, joined by MST bridges."""
    def box(size, centre):
        b = trimesh.creation.box(size)
        v, f = trimesh.remesh.subdivide_to_size(b.vertices, b.faces, max_edge=0.05)
        return trimesh.Trimesh(v + centre, f)
    seat = box([1.0, 0.1, 0.6], [0, 0.95, 0])
    leg_a = box([0.1, 0.6, 0.1], [-0.35, 0.35, 0])
    leg_b = box([0.1, 0.6, 0.1], [0.35, 0.35, 0])
    return mesh_from_trimesh(trimesh.util.concatenate([seat, leg_a, leg_b]))


def test_unconstrained_leg_stays_rigid_only_with_rigidity_term():
    m = _chair()
    g = kinetre.build_graph(m, nodes=200, seed=1)
    leg_b = np.flatnonzero((g.nodes[:, 0] > 0.25) & (g.nodes[:, 1] < 0.75))
    # leg B hangs on the rest by bridge edges only
    touching = np.isin(g.edges, leg_b).sum(axis=1) == 1
    assert touching.any() and g.bridges[touching].all()
    driven = np.setdiff1d(np.arange(g.node_count), leg_b)
    cons = node_constraints(g, driven)
    # the seat and leg A turn 50° about the vertical axis: leg B is held by bridges only
    rot = Rotation.from_euler("y", 50, degrees=True).as_matrix()
    targets = cons.points @ rot.T
    results = {}
    for w_rig in (1.0, 0.0):
        ne = NormalEquations.build(g.nodes, g.edges, g.edges[g.bridges], cons, EnergyWeights(rig=w_rig))
        rep = GaussNewton(ne, SolverSettings(max_iterations=20)).solve(identity_x(g.node_count), targets,
                                                                     np.ones(len(cons)))
        pose = kinetre.GraphPose(rep.x[:, :9].reshape(-1, 3, 3), rep.x[:, 9:])
        v = kinetre.skin(m, g, pose)
        on_b = (m.vertices[:, 0] > 0.25) & (m.vertices[:, 1] < 0.75)
        results[w_rig] = np.linalg.norm(v[on_b] - m.vertices[on_b] @ rot.T, axis=1).max()
    size = m.diagonal
    assert results[1.0] < 0.02 * size, results          # follows the chair rigidly
    assert results[0.0] > 2 * results[1.0], results     # without E_rig it swings free (Fig. 4 f)


@pytest.mark.slow
def test_real_walk_converges_every_frame(data_dir):
    from kinetre.motion.bvh import load_bvh
    from synthetic import capsule_body
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 120, 4)]
    body = capsule_body(frames[0], radius=0.06)
    g = kinetre.build_graph(body, nodes=128, seed=0)
    exact = kinetre.attach(g, frames[0], settings=SolverSettings(method="exact"))
    reference = [exact.solve(f).energy for f in frames[1:]]
    for settings in [SolverSettings(method="exact")] + PCG_DESIGNS:
        rig = kinetre.attach(g, frames[0], settings=settings)
        energies = []
        for f in frames[1:]:
            pose = rig.solve(f)
            rep = rig.last_report
            assert rep.iterations <= 10
            assert np.all(np.diff(rep.energies) < 0)
            assert np.all(np.isfinite(pose.translations))
            energies.append(rep.energy)
        # each run warm-starts from its own poses and stops at its own 1e-3 decrease: the same
        # energies frame by frame, to the exact solve's own stopping accuracy
        rel = np.array(energies) / reference - 1
        assert np.median(np.abs(rel)) < 1e-3, (settings, rel)
        if settings.method == "pcg":
            assert rel.max() < 2e-2, (settings, rel)
        # the mesh follows: the joints' constraint residuals are small against the 1.3 m skeleton
        q, ok = rig.targets(frames[-1])
        parts = rig.system.residuals(rig._x, q, ok.astype(float))
        err = np.linalg.norm(parts[4].reshape(-1, 3), axis=1)
        assert np.median(err) < 0.02 and err.max() < 0.15


PCG_DESIGNS = [SolverSettings(preconditioner=p)
               for p in ("half_cycle", "two_level")]


def test_split_reproduces_the_full_gauss_newton_system(armadillo):
    """P·blockdiag(K, K, K)·Pᵀ + node blocks + bridge blocks + damping equals the assembled JᵀJ + λD."""
    from kinetre.deform.fast import cg, hessian, preconditioner
    from kinetre.deform.fast.coordinate_split import CoordinateSplit
    m, g = armadillo
    cons, targets = _bend(g)
    ne = NormalEquations.build(g.nodes, g.edges, g.edges[g.bridges], cons, EnergyWeights())
    active = np.ones(len(cons))
    active[::3] = 0.0  # a tracked set with holes
    rng = np.random.default_rng(1)
    x = identity_x(g.node_count) + 0.2 * rng.standard_normal((g.node_count, 12))
    parts = ne.residuals(x, targets, active)
    data, _ = ne.system(x, parts, ne.const_data + ne.constraint_data(active), active)
    full = ne.matrix(data)
    split = CoordinateSplit(ne)
    (kp, ki, kx), _, _ = split.for_active(active)
    bridges = ne.bridges
    rot = np.zeros((g.node_count, 9, 9))
    rig = np.zeros((len(bridges), 18, 18))
    hessian.local_blocks(x[:, :9].reshape(-1, 3, 3), bridges, 1.0, 1.0, rot, rig)
    damp = rng.uniform(0, 1, 12 * g.node_count)
    for _ in range(3):
        v = rng.standard_normal((g.node_count, 12))
        want = full @ v.reshape(-1) + hessian.from_coordinate_layout(damp * hessian.to_coordinate_layout(v)).reshape(-1)
        got = np.empty(12 * g.node_count)
        hessian.hessian_times(kp, ki, kx, rot, rig, bridges, damp, split.shift, hessian.to_coordinate_layout(v), got)
        assert np.allclose(hessian.from_coordinate_layout(got).reshape(-1), want, rtol=1e-10, atol=1e-10 * abs(want).max())


@pytest.mark.parametrize("settings", PCG_DESIGNS, ids=lambda s: s.preconditioner)
def test_pcg_converges_to_the_exact_gauss_newton_minimum(armadillo, settings):
    m, g = armadillo
    cons, targets = _bend(g)
    ne = NormalEquations.build(g.nodes, g.edges, g.edges[g.bridges], cons, EnergyWeights())
    tight = dict(max_iterations=200, relative_tolerance=1e-10)
    exact = GaussNewton(ne, SolverSettings(method="exact", **tight)).solve(identity_x(g.node_count), targets,
                                                                          np.ones(len(cons)))
    import dataclasses
    rep = GaussNewton(ne, dataclasses.replace(settings, **tight)).solve(identity_x(g.node_count), targets,
                                                                       np.ones(len(cons)))
    assert np.all(np.diff(rep.energies) < 0)
    assert abs(rep.energy - exact.energy) <= 1e-6 * exact.energy
    pose = lambda x: kinetre.GraphPose(x[:, :9].reshape(-1, 3, 3), x[:, 9:])  # noqa: E731
    moved = kinetre.skin(m, g, pose(rep.x)) - kinetre.skin(m, g, pose(exact.x))
    assert np.abs(moved).max() < 1e-3 * m.diagonal


@pytest.mark.parametrize("backend", ["cholmod", "superlu"])
def test_coordinate_solve_inverts_the_shifted_k(armadillo, backend):
    """S r = (K_σ ⊗ I₃)⁻¹ r from either factorisation (their permutations differ); the residual
    shortcut after it equals r − H S r; PCG using these shortcuts solves the system."""
    from kinetre.deform.fast import cg, hessian, preconditioner
    from kinetre.deform.fast.coordinate_split import CoordinateSplit
    m, g = armadillo
    cons, targets = _bend(g)
    bridges = g.edges[np.arange(0, len(g.edges), 9)]
    ne = NormalEquations.build(g.nodes, g.edges, bridges, cons, EnergyWeights())
    split = CoordinateSplit(ne, backend)
    active = np.ones(len(cons))
    active[::4] = 0.0
    k, fac, k_blocks = split.for_active(active)
    n = g.node_count
    rng = np.random.default_rng(4)
    r = rng.standard_normal(12 * n)
    out, work = np.empty(12 * n), np.empty(12 * n)
    preconditioner.coordinate_solve(fac, r, out, work)
    k_sigma = split._matrix(split.k_data(active) + split.shift_data).toarray()
    want = np.linalg.solve(k_sigma, r.reshape(-1, 3)).reshape(-1)
    assert np.abs(out - want).max() < 1e-9 * np.abs(want).max()
    rot, rig = np.zeros((n, 9, 9)), np.zeros((len(bridges), 18, 18))
    x = identity_x(n) + 0.2 * rng.standard_normal((n, 12))
    hessian.local_blocks(x[:, :9].reshape(-1, 3, 3), ne.bridges, 1.0, 1.0, rot, rig)
    damp = rng.uniform(0, 0.1, 12 * n)
    z, residual = np.zeros(12 * n), r.copy()
    preconditioner.after_coordinate_solve(rot, rig, ne.bridges, damp, split.shift, z, residual, out)
    h_out = np.empty(12 * n)
    hessian.hessian_times(*k, rot, rig, ne.bridges, damp, split.shift, out, h_out)
    assert np.allclose(z, out)
    assert np.abs(residual - (r - h_out)).max() < 1e-8 * np.abs(r).max()
    # CG run long enough solves H x = r, with H p taken from the two-level preconditioner's by-products
    node_fac = preconditioner.node_factor_buffer(n)
    preconditioner.node_factors(k_blocks, rot, rig, ne.bridges, damp, node_fac)
    no_coarse = (np.zeros((0, 0)), np.zeros(n, np.int64), np.zeros((n, 3)))
    for kind in (preconditioner.TWO_LEVEL, preconditioner.HALF_CYCLE):
        x, its, converged = cg.pcg(kind, fac, *k, rot, rig, ne.bridges, damp, node_fac, no_coarse, r, 200, 1e-9)
        hessian.hessian_times(*k, rot, rig, ne.bridges, damp, split.shift, x, h_out)
        assert converged and np.abs(h_out - r).max() < 1e-7 * np.abs(r).max(), (kind, its)
    # the preconditioners that hand H z back to CG: it is H z
    z, hz, t1, t2 = (np.empty(12 * n) for _ in range(4))
    for kind in (preconditioner.TWO_LEVEL, preconditioner.HALF_CYCLE):
        assert preconditioner.precondition(kind, fac, *k, rot, rig, ne.bridges, damp, node_fac, no_coarse, r, z, hz, t1, t2,
                                    work)
        hessian.hessian_times(*k, rot, rig, ne.bridges, damp, split.shift, z, h_out)
        assert np.abs(hz - h_out).max() < 1e-9 * np.abs(h_out).max(), kind


def test_lower_inverse_inverts_stacked_triangular_blocks():
    from kinetre.deform.fast.coordinate_split import lower_inverse

    l2 = np.array([[2.0, 0.0], [3.0, 4.0]])  # by hand: [[1/2, 0], [-3/8, 1/4]]
    np.testing.assert_allclose(lower_inverse(l2[None])[0], [[0.5, 0.0], [-0.375, 0.25]], rtol=0, atol=1e-15)
    rng = np.random.default_rng(3)
    lower = np.tril(rng.normal(size=(50, 4, 4))) + 3.0 * np.eye(4)
    inverse = lower_inverse(lower)
    np.testing.assert_allclose(lower @ inverse, np.broadcast_to(np.eye(4), lower.shape), rtol=0, atol=1e-13)
    assert np.all(np.triu(inverse, 1) == 0.0)  # lower triangular, exactly


def test_fused_energy_and_gradient_match_the_sparse_forms(armadillo):
    from kinetre.deform.fast.energy import energy_gradient
    from kinetre.deform.fast.hessian import to_coordinate_layout
    m, g = armadillo
    cons, targets = _bend(g)
    weights = EnergyWeights(rot=1.3, reg=7.0, con=90.0, rig=2.0)
    bridges = g.edges[np.arange(0, len(g.edges), 7)]  # more bridges than the graph has, to exercise E_rig
    ne = NormalEquations.build(g.nodes, g.edges, bridges, cons, weights)
    rng = np.random.default_rng(2)
    x = identity_x(g.node_count) + 0.1 * rng.standard_normal((g.node_count, 12))
    active = (rng.uniform(size=len(cons)) > 0.3).astype(float)
    parts = ne.residuals(x, targets, active)
    _, want = ne.system(x, parts, None, active)
    grad = np.empty(12 * g.node_count)
    e = energy_gradient(x, ne.g, ne.edges, cons.nodes, cons.weights, cons.points, targets, active,
                        ne.bridges, weights.rot, weights.reg, weights.con, weights.rig, grad, True)
    assert e == pytest.approx(ne.energy(parts), rel=1e-12)
    assert np.allclose(grad, to_coordinate_layout(want), rtol=1e-10, atol=1e-10 * np.abs(want).max())


def test_node_blocks_invert_the_diagonal_blocks_of_the_system(armadillo):
    from kinetre.deform.fast import cg, hessian, preconditioner
    from kinetre.deform.fast.coordinate_split import CoordinateSplit
    m, g = armadillo
    cons, targets = _bend(g)
    bridges = g.edges[np.arange(0, len(g.edges), 9)]
    ne = NormalEquations.build(g.nodes, g.edges, bridges, cons, EnergyWeights())
    (kp, ki, kx), _, k_blocks = CoordinateSplit(ne).for_active(np.ones(len(cons)))
    rng = np.random.default_rng(3)
    x = identity_x(g.node_count) + 0.2 * rng.standard_normal((g.node_count, 12))
    n = g.node_count
    rot, rig = np.zeros((n, 9, 9)), np.zeros((len(bridges), 18, 18))
    hessian.local_blocks(x[:, :9].reshape(-1, 3, 3), ne.bridges, 1.0, 1.0, rot, rig)
    damp = rng.uniform(0, 0.1, 12 * n)
    fac = preconditioner.node_factor_buffer(n)
    preconditioner.node_factors(k_blocks, rot, rig, ne.bridges, damp, fac)
    # the diagonal blocks of H, read off by multiplying H with unit vectors node by node
    blocks = np.zeros((n, 12, 12))
    for u in range(12):
        e = np.zeros(12 * n)
        e[u::12] = 1.0
        he = np.empty(12 * n)
        hessian.hessian_times(kp, ki, kx, rot, rig, ne.bridges, damp, np.zeros(12 * n), e, he)
        # other nodes' unit entries leak into a node's rows through off-diagonal blocks: remove them
        he -= _offdiagonal_part(kp, ki, kx, rig, ne.bridges, e, n)
        blocks[:, :, u] = he.reshape(n, 12)
    r = rng.standard_normal(12 * n)
    out = np.empty(12 * n)
    preconditioner.node_solve(fac, r, out)
    want = np.linalg.solve(blocks, r.reshape(n, 12, 1))[..., 0]
    assert np.allclose(out.reshape(n, 12), want, rtol=1e-9, atol=1e-9 * np.abs(want).max())


def _offdiagonal_part(kp, ki, kx, rig, bridges, y, n):
    """The node-to-other-node part of H y: K's blocks between different nodes, bridges' cross blocks."""
    out = np.zeros(12 * n)
    y4 = y.reshape(-1, 4, 3)  # per node, unknown b's coordinate a
    for i in range(len(kp) - 1):
        for p in range(kp[i], kp[i + 1]):
            if ki[p] != i:
                out[12 * i:12 * i + 12] += (kx[p].reshape(4, 4) @ y4[ki[p]]).reshape(-1)
    for e, (j, k) in enumerate(bridges):
        out[12 * j:12 * j + 9] += rig[e, :9, 9:] @ y[12 * k:12 * k + 9]
        out[12 * k:12 * k + 9] += rig[e, 9:, :9] @ y[12 * j:12 * j + 9]
    return out


def test_default_follows_the_exact_solve_when_few_nodes_are_constrained(data_dir):
    """One arm possesses a whole body: most of the graph is held only by E_reg/E_rot, where block
    Jacobi alone stalls; the default's per-coordinate factor carries that coupling."""
    from kinetre.motion.bvh import load_bvh
    from synthetic import capsule_body
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 160, 4)]
    g = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=128, seed=0)
    exact = kinetre.attach(g, frames[0], subset="right arm", settings=SolverSettings(method="exact"))
    rig = kinetre.attach(g, frames[0], subset="right arm")
    rel = []
    for f in frames[1:]:
        e_exact = exact.solve(f).energy
        rig.solve(f)
        assert np.all(np.diff(rig.last_report.energies) < 0)
        rel.append(rig.last_report.energy / e_exact - 1)
    assert np.median(rel) < 1e-3 and max(rel) < 2e-2, rel


def test_stretch_curvature_completes_the_rotation_hessian_on_stretched_columns():
    """With orthogonal, stretched columns E_rot's cross residuals vanish, so Gauss-Newton's block plus
    `stretch_curvature` is E_rot's exact Hessian (½ ∇²E by central differences of its gradient); with
    shrunk columns nothing is added (that curvature is negative and left out)."""
    from scipy.spatial.transform import Rotation

    from kinetre.deform.fast import cg, hessian, preconditioner
    from kinetre.deform.fast.energy import energy_gradient
    q = Rotation.from_euler("xyz", [30, -20, 50], degrees=True).as_matrix()
    w_rot = 1.7
    none = np.zeros((0, 2), np.int64)

    def gradient(x):  # ½ ∇E_rot in the coordinate layout
        grad = np.empty(12)
        energy_gradient(x.reshape(1, 12), np.zeros((1, 3)), none, np.zeros((0, 4), np.int32),
                        np.zeros((0, 4)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), none,
                        w_rot, 0.0, 0.0, 0.0, grad, True)
        return grad

    for scale, added in (([1.3, 1.1, 1.2], True), ([0.8, 0.9, 0.7], False)):
        R = q * np.array(scale)  # columns q_b scaled: orthogonal
        x = np.concatenate([R.reshape(-1), np.zeros(3)])
        rot, rig = np.zeros((1, 9, 9)), np.zeros((0, 18, 18))
        hessian.local_blocks(R[None], none, w_rot, 0.0, rot, rig)
        gauss_newton = rot[0].copy()
        hessian.stretch_curvature(R[None], w_rot, rot)
        h = 1e-6
        exact = np.empty((9, 9))
        for u in range(9):  # coordinate-layout unknown u is R[u % 3, u // 3] (x index 3 (u % 3) + u // 3)
            e = np.zeros(12)
            e[3 * (u % 3) + u // 3] = h
            exact[:, u] = ((gradient(x + e) - gradient(x - e)) / (2 * h))[:9]
        if added:
            assert np.allclose(rot[0], exact, atol=1e-6 * np.abs(exact).max())
            assert not np.allclose(gauss_newton, exact, atol=1e-2 * np.abs(exact).max())
        else:
            assert np.array_equal(rot[0], gauss_newton)
        assert np.linalg.eigvalsh(rot[0]).min() > -1e-12


def test_constant_velocity_start_is_taken_only_when_it_lowers_the_energy(data_dir):
    """Each frame starts from the last pose or from its extrapolation at constant velocity, whichever has
    the lower E; the frame's result is never above either."""
    from kinetre.motion.bvh import load_bvh
    from synthetic import capsule_body
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 100, 4)]
    rig = kinetre.attach(kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=96, seed=0), frames[0])
    taken = 0
    for f in frames[1:]:
        q, ok = rig.targets(f)
        active = ok.astype(float)
        e_last = rig.solver.energy(rig._x, q, active)
        e_guess = np.inf if rig._x_before is None else rig.solver.energy(2 * rig._x - rig._x_before, q, active)
        rig.solve(f)
        rep = rig.last_report
        assert rep.energies[0] == pytest.approx(min(e_last, e_guess), rel=1e-12)
        assert rep.energy <= min(e_last, e_guess)
        taken += e_guess < e_last
    assert taken >= len(frames) // 2  # on a walk the extrapolation usually fits better
