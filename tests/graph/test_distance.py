"""Eq. 6 properties: D ≥ Euclidean, symmetric, 3× off-plane, ∞ past 90°, numba = numpy."""
import numpy as np

from kinetre.graph.distance import distance_5d, orientation_aware_distance


def _random_oriented(rng, n):
    p = rng.standard_normal((n, 3))
    nrm = rng.standard_normal((n, 3))
    return p, nrm / np.linalg.norm(nrm, axis=1)[:, None]


def test_bounds_euclidean_and_symmetric():
    rng = np.random.default_rng(0)
    p, n_p = _random_oriented(rng, 2000)
    q, n_q = _random_oriented(rng, 2000)
    d = orientation_aware_distance(p, n_p, q, n_q)
    assert np.all(d >= np.linalg.norm(p - q, axis=1) * (1 - 1e-12))
    assert np.allclose(d, orientation_aware_distance(q, n_q, p, n_p), equal_nan=False)


def test_tangent_plane_is_euclidean_normal_direction_is_tripled():
    up = np.array([0.0, 0.0, 1.0])
    assert np.isclose(orientation_aware_distance(np.zeros(3), up, np.array([0.3, 0.4, 0.0]), up), 0.5)
    assert np.isclose(orientation_aware_distance(np.zeros(3), up, np.array([0.0, 0.0, 0.5]), up), 1.5)


def test_infinite_at_or_past_ninety_degrees():
    a, b = np.array([0.0, 0, 1]), np.array([1.0, 0, 0])
    assert np.isinf(orientation_aware_distance(np.zeros(3), a, np.ones(3), b))
    assert np.isinf(orientation_aware_distance(np.zeros(3), a, np.ones(3), -a))


def test_tilted_normals_divide_by_cosine():
    a = np.array([0.0, 0, 1])
    b = np.array([np.sin(np.pi / 3), 0, np.cos(np.pi / 3)])  # 60° apart: cos = 1/2
    q = np.array([0.0, 1.0, 0.0])  # in both tangent planes
    assert np.isclose(orientation_aware_distance(np.zeros(3), a, q, b), 2.0)


def test_numba_matches_numpy():
    rng = np.random.default_rng(1)
    p, n_p = _random_oriented(rng, 300)
    q, n_q = _random_oriented(rng, 300)
    ref = orientation_aware_distance(p, n_p, q, n_q)
    got = np.array([distance_5d(*p[i], *n_p[i], *q[i], *n_q[i]) for i in range(300)])
    assert np.allclose(got, ref) and np.array_equal(np.isinf(got), np.isinf(ref))
