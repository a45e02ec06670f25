"""Eq. 6: the 5D orientation-aware distance D(p, q) between oriented surface samples.

dist_q(p) = ‖(p − q) + 2((p − q)·n_q) n_q‖ squashes the sphere around q to 1/3 along n_q;
D(p, q) = min(dist_q(p), dist_p(q)) / max(0, n_p·n_q), infinite when the normals are ≥ 90° apart.
Since D ≥ ‖p − q‖, every neighbour with D < R lies within Euclidean R (we prune with grids/KD-trees).
"""
from __future__ import annotations

import numpy as np
from ..jit import njit


def orientation_aware_distance(p: np.ndarray, n_p: np.ndarray, q: np.ndarray, n_q: np.ndarray) -> np.ndarray:
    """D(p, q) of Eq. 6, broadcast over leading axes.

    Parameters
    ----------
    p, q : (..., 3) float
        Sample positions.
    n_p, n_q : (..., 3) float
        Their unit normals.

    Returns
    -------
    (...,) float64, ≥ ‖p − q‖; inf where n_p·n_q ≤ 0.

    >>> import numpy as np
    >>> up = np.array([0.0, 0.0, 1.0])
    >>> float(orientation_aware_distance(np.zeros(3), up, np.array([1.0, 0, 0]), up))  # in-plane: Euclidean
    1.0
    >>> float(orientation_aware_distance(np.zeros(3), up, np.array([0, 0, 1.0]), up))  # off-plane: ×3
    3.0
    """
    d = np.asarray(p, dtype=np.float64) - np.asarray(q, dtype=np.float64)
    dd = np.einsum("...i,...i->...", d, d)
    a = np.einsum("...i,...i->...", d, n_q)
    b = np.einsum("...i,...i->...", d, n_p)
    # ‖d + 2(d·n)n‖² = |d|² + 8 (d·n)² for a unit n
    num = np.sqrt(dd + 8.0 * np.minimum(a * a, b * b))
    cos = np.einsum("...i,...i->...", n_p, n_q)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(cos > 0.0, num / np.where(cos > 0.0, cos, 1.0), np.inf)


@njit(cache=True, inline="always")
def distance_5d(px, py, pz, npx, npy, npz, qx, qy, qz, nqx, nqy, nqz):
    """Scalar D(p, q) for numba loops (same formula as `orientation_aware_distance`)."""
    cos = npx * nqx + npy * nqy + npz * nqz
    if cos <= 0.0:
        return np.inf
    dx = px - qx
    dy = py - qy
    dz = pz - qz
    a = dx * nqx + dy * nqy + dz * nqz
    b = dx * npx + dy * npy + dz * npz
    m = a * a if a * a < b * b else b * b
    return np.sqrt(dx * dx + dy * dy + dz * dz + 8.0 * m) / cos
