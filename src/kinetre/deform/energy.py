"""The embedded-deformation energy, one function per term (Eq. 2, 3, 4, 5, 7, 8): the definition.

Unknowns: per node j an affine R_j (3×3) and a translation t_j, with A_j[v] = R_j (v − g_j) + g_j + t_j
(Eq. 1). Each term returns its residual vector r so that the term equals ‖r‖²; Gauss-Newton works on
the stacked, weighted residuals. The exact reference solve (`normal_equations.py`) takes its residuals from
here; the fast path evaluates the same sums, with the gradient, in one numba kernel (`fast/energy.py`),
which the tests check against these.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .constraints import PointConstraints


@dataclass(frozen=True)
class EnergyWeights:
    """Eq. 8 weights: Sumner et al.'s w_rot = 1, w_reg = 10, w_con = 100, and w_rig = w_reg / 10."""

    rot: float = 1.0
    reg: float = 10.0
    con: float = 100.0
    rig: float = 1.0


# A skeleton standing where the mesh's artist put it constrains every node by its bone (`attach_skeleton`'s node
# bones), so E_reg need not fill in unconstrained nodes, only tie neighbours together: a stronger E_con keeps
# each part on its own bone where parts meet.
CARRIED = EnergyWeights(con=400.0)


def rotation_residuals(R: np.ndarray) -> np.ndarray:
    """Eq. 3 in Sumner's Gauss-Newton form: 6 residuals per node.

    c1·c2, c1·c3, c2·c3, c1·c1 − 1, c2·c2 − 1, c3·c3 − 1 over the columns c of R_j.
    Returns (N, 6).
    """
    c = R  # c[:, :, b] is column b
    dots = np.einsum("nab,nac->nbc", c, c)
    return np.stack([dots[:, 0, 1], dots[:, 0, 2], dots[:, 1, 2],
                     dots[:, 0, 0] - 1, dots[:, 1, 1] - 1, dots[:, 2, 2] - 1], axis=1)


def regularization_residuals(R: np.ndarray, t: np.ndarray, g: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Eq. 4: A_j[g_k] − A_k[g_k] for every neighbour k of j (both directions of each edge).

    Returns (2E, 3): first the (j→k) rows for edges (j, k), then the (k→j) rows.
    """
    j = np.concatenate([edges[:, 0], edges[:, 1]])
    k = np.concatenate([edges[:, 1], edges[:, 0]])
    return np.einsum("nab,nb->na", R[j], g[k] - g[j]) + g[j] + t[j] - g[k] - t[k]


def carriers(R: np.ndarray, t: np.ndarray, g: np.ndarray, constraints: PointConstraints) -> np.ndarray:
    """Eq. 2 at the constraint points: φ(p_ℓ) = Σ_i w_i A_i[p_ℓ] over the nodes carrying each. Returns (L, 3)."""
    p = constraints.points
    idx = constraints.nodes
    moved = np.einsum("lkab,lkb->lka", R[idx], p[:, None, :] - g[idx]) + g[idx] + t[idx]
    return np.einsum("lk,lka->la", constraints.weights, moved)


def constraint_residuals(R: np.ndarray, t: np.ndarray, g: np.ndarray, constraints: PointConstraints,
                         targets: np.ndarray) -> np.ndarray:
    """Eq. 5: φ(p_ℓ) − q_ℓ with φ the Eq. 2 blend (`carriers`). Returns (L, 3)."""
    return carriers(R, t, g, constraints) - targets


def rigidity_residuals(R: np.ndarray, t: np.ndarray, g: np.ndarray, bridges: np.ndarray) -> np.ndarray:
    """Eq. 7 on bridge edges (j, k): R_kᵀ R_j − I (9 residuals) and the translation gap (3).

    The paper writes the gap as t_k − t_j; we take it as A_j[m] − A_k[m] at the edge midpoint m,
    which equals t_j − t_k whenever R_j = R_k = I but costs nothing under a global rigid motion
    (ours: otherwise a rotated mesh would be pulled back towards its rest orientation).
    Returns (B, 12).
    """
    j, k = bridges[:, 0], bridges[:, 1]
    rr = np.einsum("nca,ncb->nab", R[k], R[j]) - np.eye(3)
    m = 0.5 * (g[j] + g[k])
    gap = (np.einsum("nab,nb->na", R[j], m - g[j]) + g[j] + t[j]
           - np.einsum("nab,nb->na", R[k], m - g[k]) - g[k] - t[k])
    return np.concatenate([rr.reshape(-1, 9), gap], axis=1)


def total_energy(R: np.ndarray, t: np.ndarray, g: np.ndarray, edges: np.ndarray, bridges: np.ndarray,
                 constraints: PointConstraints, targets: np.ndarray, active: np.ndarray,
                 weights: EnergyWeights = EnergyWeights()) -> float:
    """Eq. 8: E = w_rot E_rot + w_reg E_reg + w_con E_con + w_rig E_rig.

    `active` (L,) scales each constraint (0 drops an untracked joint for this frame).
    """
    e_rot = np.sum(rotation_residuals(R) ** 2)
    e_reg = np.sum(regularization_residuals(R, t, g, edges) ** 2)
    e_con = np.sum((active[:, None] * constraint_residuals(R, t, g, constraints, targets)) ** 2)
    e_rig = np.sum(rigidity_residuals(R, t, g, bridges) ** 2) if len(bridges) else 0.0
    return float(weights.rot * e_rot + weights.reg * e_reg + weights.con * e_con + weights.rig * e_rig)
