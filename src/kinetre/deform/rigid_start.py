"""A jump frame's rigid start: the current pose carried by the rigid motion that best takes the constraint
points to their new targets (a skeleton teleporting moves the whole graph mostly rigidly).

With φ(p_ℓ) the deformed carriers of the constraints (Eq. 2) at the pose x and q_ℓ their targets, the
rotation R and centroids c, c' minimise Σ_ℓ a_ℓ² ‖R (φ(p_ℓ) − c) + c' − q_ℓ‖² (weighted Kabsch / Umeyama
without scale, a_ℓ = `active`, which scales each residual of E_con: the same weights). At a converged pose
E's gradient along a global rigid motion is zero, so R = I there; constraints all moved by one rigid
motion are met by that motion exactly. Composing every node with it,
A'_j = R A_j and t'_j such that g_j + t_j goes to R (g_j + t_j − c) + c', maps every point as
A'_j[v] = R (A_j[v] − c) + c': E_rot, E_reg and E_rig (ours: its gap taken at the edge midpoint, so
invariant under a rigid motion) are unchanged and only E_con moves. The solver offers it as a start kept only
when its energy is lower (ours: the frame then often needs no more steps than a usual one).
"""
from __future__ import annotations

import numpy as np

from .constraints import PointConstraints
from .energy import carriers as energy_carriers


def carriers(x: np.ndarray, g: np.ndarray, constraints: PointConstraints) -> np.ndarray:
    """φ(p_ℓ) = Σ_i w_i A_i[p_ℓ] (Eq. 2) at the pose x (N, 12): rows R_j (row-major) then t_j. Returns (L, 3)."""
    return energy_carriers(x[:, :9].reshape(-1, 3, 3), x[:, 9:], g, constraints)


def best_rotation(source: np.ndarray, target: np.ndarray, weights: np.ndarray):
    """Weighted Kabsch: (R, c, c') minimising Σ w_ℓ ‖R (s_ℓ − c) + c' − t_ℓ‖² over rotations (det R = +1).

    c, c' are the weighted centroids. Fewer than three independent points leave R partly free: the SVD
    then picks one of the minimisers. Returns None when no weight is positive.
    """
    w = np.clip(np.asarray(weights, dtype=np.float64), 0.0, None)
    total = w.sum()
    if not total > 0.0:
        return None
    c = w @ source / total
    c_new = w @ target / total
    cov = (target - c_new).T @ (w[:, None] * (source - c))  # Σ w (t − c')(s − c)ᵀ
    u, _, vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0  # a reflection is not a motion
    rotation = u @ np.diag([1.0, 1.0, d]) @ vt
    return rotation, c, c_new


def rigid_start(x: np.ndarray, g: np.ndarray, constraints: PointConstraints, targets: np.ndarray,
                active: np.ndarray) -> np.ndarray | None:
    """The pose x (N, 12) composed with the best rigid motion of its constraint carriers onto `targets` (L, 3),
    weighted by `active` (L,). Returns a new (N, 12) array, or None when no constraint is active or the
    targets are not finite."""
    on = np.asarray(active) > 0
    if not on.any() or not np.isfinite(targets[on]).all():
        return None
    fit = best_rotation(carriers(x, g, constraints)[on], targets[on], active[on] ** 2)
    if fit is None:
        return None
    rotation, c, c_new = fit
    out = np.empty_like(x)
    out[:, :9] = np.einsum("ab,nbc->nac", rotation, x[:, :9].reshape(-1, 3, 3)).reshape(-1, 9)
    out[:, 9:] = (g + x[:, 9:] - c) @ rotation.T + c_new - g
    return out
