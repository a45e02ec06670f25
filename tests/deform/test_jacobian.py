"""Each term's analytic Jacobian against central finite differences, and the fast assembly against JᵀJ."""
import numpy as np
import pytest

from kinetre.deform import energy as en
from kinetre.deform import jacobian as jac
from kinetre.deform.constraints import PointConstraints
from kinetre.deform.energy import EnergyWeights
from kinetre.deform.normal_equations import NormalEquations


@pytest.fixture(scope="module")
def rig():
    rng = np.random.default_rng(42)
    n = 9
    g = rng.standard_normal((n, 3))
    edges = np.array([[i, j] for i in range(n) for j in range(i + 1, n) if (i + j) % 3 == 0 or j == i + 1],
                     dtype=np.int32)
    bridges = edges[::3]
    L = 7
    idx = np.stack([rng.choice(n, 4, replace=False) for _ in range(L)]).astype(np.int32)
    w = rng.random((L, 4))
    w /= w.sum(axis=1, keepdims=True)
    cons = PointConstraints(rng.standard_normal((L, 3)), idx, w)
    R = np.eye(3) + 0.3 * rng.standard_normal((n, 3, 3))
    t = 0.3 * rng.standard_normal((n, 3))
    targets = rng.standard_normal((L, 3))
    return dict(g=g, edges=edges, bridges=bridges, cons=cons, R=R, t=t, targets=targets, n=n)


def _fd(f, x, eps=1e-6):
    cols = []
    for i in range(x.size):
        xp, xm = x.copy(), x.copy()
        xp.flat[i] += eps
        xm.flat[i] -= eps
        cols.append((f(xp) - f(xm)) / (2 * eps))
    return np.stack(cols, axis=1)


def _unpack(x):
    x = x.reshape(-1, 12)
    return x[:, :9].reshape(-1, 3, 3), x[:, 9:]


def _x(r):
    return np.concatenate([r["R"].reshape(-1, 9), r["t"]], axis=1).reshape(-1)


def test_rotation_jacobian(rig):
    num = _fd(lambda x: en.rotation_residuals(_unpack(x)[0]).reshape(-1), _x(rig))
    assert np.allclose(jac.rotation_jacobian(rig["R"]).toarray(), num, atol=1e-7)


def test_regularization_jacobian(rig):
    num = _fd(lambda x: en.regularization_residuals(*_unpack(x), rig["g"], rig["edges"]).reshape(-1), _x(rig))
    assert np.allclose(jac.regularization_jacobian(rig["g"], rig["edges"]).toarray(), num, atol=1e-7)


def test_constraint_jacobian(rig):
    f = lambda x: en.constraint_residuals(*_unpack(x), rig["g"], rig["cons"], rig["targets"]).reshape(-1)
    assert np.allclose(jac.constraint_jacobian(rig["g"], rig["cons"]).toarray(), _fd(f, _x(rig)), atol=1e-7)


def test_rigidity_jacobian(rig):
    f = lambda x: en.rigidity_residuals(*_unpack(x), rig["g"], rig["bridges"]).reshape(-1)
    assert np.allclose(jac.rigidity_jacobian(rig["R"], rig["g"], rig["bridges"]).toarray(), _fd(f, _x(rig)),
                       atol=1e-7)


def test_fast_assembly_matches_reference_normal_equations(rig):
    w = EnergyWeights(rot=1.3, reg=10, con=100, rig=0.7)
    active = np.array([1, 1, 0, 1, 0.5, 1, 1], float)
    ne = NormalEquations.build(rig["g"], rig["edges"], rig["bridges"], rig["cons"], w)
    x = _x(rig).reshape(-1, 12)
    parts = ne.residuals(x, rig["targets"], active)
    data, grad = ne.system(x, parts, ne.const_data + ne.constraint_data(active), active)
    s = np.repeat(active, 3)[:, None]
    J = np.vstack([np.sqrt(w.rot) * jac.rotation_jacobian(rig["R"]).toarray(),
                   np.sqrt(w.reg) * jac.regularization_jacobian(rig["g"], rig["edges"]).toarray(),
                   np.sqrt(w.con) * s * jac.constraint_jacobian(rig["g"], rig["cons"]).toarray(),
                   np.sqrt(w.rig) * jac.rigidity_jacobian(rig["R"], rig["g"], rig["bridges"]).toarray()])
    R, t = rig["R"], rig["t"]
    r = np.concatenate([np.sqrt(w.rot) * en.rotation_residuals(R).reshape(-1),
                        np.sqrt(w.reg) * en.regularization_residuals(R, t, rig["g"], rig["edges"]).reshape(-1),
                        np.sqrt(w.con) * (active[:, None] * en.constraint_residuals(
                            R, t, rig["g"], rig["cons"], rig["targets"])).reshape(-1),
                        np.sqrt(w.rig) * en.rigidity_residuals(R, t, rig["g"], rig["bridges"]).reshape(-1)])
    assert np.allclose(ne.matrix(data).toarray(), J.T @ J, atol=1e-9)
    assert np.allclose(grad, J.T @ r, atol=1e-9)
    assert np.isclose(ne.energy(parts), r @ r)
    assert np.isclose(ne.energy(parts), en.total_energy(R, t, rig["g"], rig["edges"], rig["bridges"], rig["cons"],
                                                        rig["targets"], active, w))
