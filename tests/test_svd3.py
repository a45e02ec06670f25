"""The batched 3 × 3 SVD against LAPACK's, on random, near-rotation and rank-deficient matrices."""
import numpy as np

from kinetre.svd3 import det3, svd3


def test_svd3_matches_lapack_and_reconstructs():
    rng = np.random.default_rng(7)
    m = rng.normal(size=(2000, 3, 3))
    m[:1000] = np.eye(3) + 1e-3 * rng.normal(size=(1000, 3, 3))  # what a solved pose holds
    m[1000] = 0.0
    m[1001] = np.outer([1.0, 2.0, 3.0], [4.0, 5.0, 6.0])
    m[1002] = np.diag([1.0, 1.0, 0.0])
    m[1003] = -np.eye(3)
    m[1004] = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [1.0, 1.0, 1.0]]
    u, s, vt = svd3(m.reshape(2, 1000, 3, 3))
    u, s, vt = u.reshape(-1, 3, 3), s.reshape(-1, 3), vt.reshape(-1, 3, 3)
    np.testing.assert_allclose(s, np.linalg.svd(m, compute_uv=False), atol=1e-13)
    np.testing.assert_allclose((u * s[:, None, :]) @ vt, m, atol=1e-13)
    eye = np.broadcast_to(np.eye(3), m.shape)
    np.testing.assert_allclose(u @ u.transpose(0, 2, 1), eye, atol=1e-13)
    np.testing.assert_allclose(vt @ vt.transpose(0, 2, 1), eye, atol=1e-13)
    assert np.all(np.diff(s, axis=1) <= 0.0) and np.all(s >= 0.0)
    np.testing.assert_allclose(det3(m), np.linalg.det(m), atol=1e-12)
