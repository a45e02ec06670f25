"""Gauss-Newton normal equations JᵀJ δ = −Jᵀr, assembled into a sparsity pattern fixed per rig.

E_reg (Eq. 4), E_con (Eq. 5) and the translation gap of E_rig (Eq. 7) are linear in x, so their part
of JᵀJ is built once (the constraint part again only when the set of tracked constraints changes).
Per iteration only the 9×9 blocks of E_rot (Eq. 3) and the 18×18 blocks of E_rig's R_kᵀR_j − I are
recomputed, in numba, and scattered to positions found once. The pattern is the exact scalar one
(the product of the structural Jacobians), which keeps the factorisation ~5× cheaper than dense
12×12 blocks.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csc_matrix, csr_matrix, identity

from ..jit import njit
from .constraints import PointConstraints
from .energy import (EnergyWeights, constraint_residuals, regularization_residuals, rigidity_residuals,
                     rotation_residuals)
from .jacobian import (ROT_P, ROT_Q, constraint_jacobian, regularization_jacobian, rigidity_jacobian,
                       rotation_jacobian)


def positions(indptr: np.ndarray, indices: np.ndarray, n: int, rows, cols) -> np.ndarray:
    """Index into a CSC data array of each (row, col) entry, which must exist in the pattern."""
    col_of = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    keys = col_of * n + indices
    want = np.asarray(cols, dtype=np.int64) * n + np.asarray(rows, dtype=np.int64)
    pos = np.searchsorted(keys, want)
    assert_in = keys[np.minimum(pos, len(keys) - 1)] == want
    if not assert_in.all():
        raise RuntimeError("normal-equation entry outside the analysed pattern")
    return pos


def scatter(pattern_indptr, pattern_indices, n, m) -> np.ndarray:
    """A sparse matrix's values laid out on the pattern (zeros elsewhere)."""
    m = m.tocoo()
    data = np.zeros(len(pattern_indices))
    np.add.at(data, positions(pattern_indptr, pattern_indices, n, m.row, m.col), m.data)
    return data


@dataclass(frozen=True, eq=False)
class NormalEquations:
    """Everything about JᵀJ that stays fixed for one rig (graph + constraints)."""

    n: int
    indptr: np.ndarray
    indices: np.ndarray
    rot_pos: np.ndarray      # (N, 9, 9) data positions of node j's R-R entries
    rig_pos: np.ndarray      # (B, 18, 18) positions of [R_j, R_k] pairs of each bridge
    diag_pos: np.ndarray     # (12N,)
    bridges: np.ndarray      # (B, 2) int64
    const_data: np.ndarray   # w_reg J_regᵀJ_reg + w_rig J_gapᵀJ_gap on the pattern
    j_reg: csr_matrix
    b_reg: np.ndarray
    j_gap: csr_matrix
    b_gap: np.ndarray
    j_con: csr_matrix
    b_con: np.ndarray        # constant part of the constraint residual before subtracting q
    weights: EnergyWeights
    g: np.ndarray | None = None                      # the terms' raw data (`energy.py`, `fast/energy.py`)
    edges: np.ndarray | None = None
    constraints: PointConstraints | None = None

    @staticmethod
    def build(g: np.ndarray, edges: np.ndarray, bridge_edges: np.ndarray, constraints: PointConstraints,
              weights: EnergyWeights) -> "NormalEquations":
        nodes = len(g)
        n = 12 * nodes
        rng = np.random.default_rng(0)
        r_any = np.abs(rng.standard_normal((nodes, 3, 3))) + 1.0
        j_reg = regularization_jacobian(g, edges)
        j_con = constraint_jacobian(g, constraints)
        j_rig = rigidity_jacobian(r_any, g, bridge_edges)
        gap_rows = (12 * np.arange(len(bridge_edges))[:, None] + 9 + np.arange(3)).reshape(-1)
        j_gap = j_rig[gap_rows] if len(bridge_edges) else csr_matrix((0, n))

        def structural(m):
            m = m.copy()
            m.data = np.ones_like(m.data)  # positive values: products cannot cancel
            return m

        pattern = (structural(j_reg).T @ structural(j_reg) + structural(j_con).T @ structural(j_con)
                   + structural(j_rig).T @ structural(j_rig)
                   + structural(rotation_jacobian(r_any)).T @ structural(rotation_jacobian(r_any))
                   + identity(n, format="csr")).tocsc()
        pattern.sort_indices()
        indptr, indices = pattern.indptr.astype(np.int64), pattern.indices.astype(np.int64)

        jj = np.arange(nodes)
        rv = np.arange(9)
        rot_cols = 12 * jj[:, None] + rv[None, :]                      # (N, 9)
        rot_pos = positions(indptr, indices, n, np.repeat(rot_cols, 9, axis=1).reshape(-1),
                             np.tile(rot_cols, (1, 9)).reshape(-1)).reshape(nodes, 9, 9)
        b = np.asarray(bridge_edges, dtype=np.int64).reshape(-1, 2)
        rig_cols = np.concatenate([12 * b[:, :1] + rv, 12 * b[:, 1:] + rv], axis=1)  # (B, 18)
        rig_pos = positions(indptr, indices, n, np.repeat(rig_cols, 18, axis=1).reshape(-1),
                             np.tile(rig_cols, (1, 18)).reshape(-1)).reshape(len(b), 18, 18)
        diag_pos = positions(indptr, indices, n, np.arange(n), np.arange(n))

        const = weights.reg * (j_reg.T @ j_reg)
        if len(b):
            const = const + weights.rig * (j_gap.T @ j_gap)
        e0 = np.concatenate([edges[:, 0], edges[:, 1]])
        e1 = np.concatenate([edges[:, 1], edges[:, 0]])
        b_reg = (g[e0] - g[e1]).reshape(-1)
        b_gap = (g[b[:, 0]] - g[b[:, 1]]).reshape(-1)
        b_con = np.einsum("lk,lka->la", constraints.weights, g[constraints.nodes]).reshape(-1) \
            if len(constraints) else np.zeros(0)
        return NormalEquations(n, indptr, indices, rot_pos, rig_pos, diag_pos, b,
                               scatter(indptr, indices, n, const), j_reg.tocsr(), b_reg, j_gap.tocsr(), b_gap,
                               j_con.tocsr(), b_con, weights, np.ascontiguousarray(g, dtype=np.float64),
                               np.ascontiguousarray(edges, dtype=np.int64), constraints)

    def constraint_data(self, active: np.ndarray) -> np.ndarray:
        """w_con J_conᵀ S² J_con on the pattern, for the per-constraint scales `active` (L,)."""
        s2 = np.repeat(np.asarray(active, dtype=np.float64) ** 2, 3)
        m = self.j_con.T @ (self.j_con.multiply(s2[:, None]).tocsr())
        return self.weights.con * scatter(self.indptr, self.indices, self.n, m)

    def residuals(self, x: np.ndarray, targets: np.ndarray, active: np.ndarray):
        """Unweighted residual blocks (rot, rig-R, reg, gap, con) at x (N, 12), flat, from the terms'
        definitions (`energy.py`): the rows of the Jacobians here."""
        R = x[:, :9].reshape(-1, 3, 3)
        t = x[:, 9:]
        r_rig = rigidity_residuals(R, t, self.g, self.bridges)
        r_con = np.asarray(active, dtype=np.float64)[:, None] * constraint_residuals(R, t, self.g, self.constraints,
                                                                                     targets)
        return (rotation_residuals(R).reshape(-1), r_rig[:, :9].reshape(-1),
                regularization_residuals(R, t, self.g, self.edges).reshape(-1), r_rig[:, 9:].reshape(-1),
                r_con.reshape(-1))

    def energy(self, parts) -> float:
        r_rot, r_rig, r_reg, r_gap, r_con = parts
        w = self.weights
        return float(w.rot * r_rot @ r_rot + w.rig * (r_rig @ r_rig + r_gap @ r_gap)
                     + w.reg * r_reg @ r_reg + w.con * r_con @ r_con)

    def system(self, x: np.ndarray, parts, linear_data: np.ndarray | None, active: np.ndarray):
        """(JᵀJ data on the pattern, gradient Jᵀr) at x; `linear_data` = const + constraint data.

        With `linear_data` None only the gradient is formed (the data is returned as None): a step
        with a reused factor needs no new JᵀJ.
        """
        R = x[:, :9].reshape(-1, 3, 3)
        r_rot, r_rig, r_reg, r_gap, r_con = parts
        w = self.weights
        hessian = linear_data is not None
        data = linear_data.copy() if hessian else np.zeros(1)
        grad = np.zeros(self.n)
        _add_rotation(data, grad, self.rot_pos, R, r_rot, w.rot, hessian)
        _add_rigidity(data, grad, self.rig_pos, self.bridges, R, r_rig, w.rig, hessian)
        grad += w.reg * (self.j_reg.T @ r_reg)
        grad += w.con * (self.j_con.T @ (r_con * np.repeat(active, 3)))
        if len(self.bridges):
            grad += w.rig * (self.j_gap.T @ r_gap)
        return (data if hessian else None), grad

    def matrix(self, data: np.ndarray) -> csc_matrix:
        # int32 indices: CHOLMOD's int interface takes them without a copy
        m = csc_matrix((self.n, self.n))
        m.data, m.indices, m.indptr = data, self._indices32, self._indptr32
        m.has_sorted_indices = True
        return m

    def __post_init__(self):
        object.__setattr__(self, "_indices32", self.indices.astype(np.int32))
        object.__setattr__(self, "_indptr32", self.indptr.astype(np.int32))


@njit(cache=True)
def rotation_block_jacobian(R, j, coordinate, jac):
    """Eq. 3's (6, 9) Jacobian of node j over its R entries: R[a, b] at 3 a + b, or at 3 b + a in the
    `coordinate` layout of `fast/hessian.py`. d(c_p·c_q)/dR[a, p] = R[a, q] and d/dR[a, q] = R[a, p]."""
    jac[:] = 0.0
    for r in range(6):
        p = ROT_P[r]
        q = ROT_Q[r]
        for a in range(3):
            jac[r, 3 * p + a if coordinate else 3 * a + p] += R[j, a, q]
            jac[r, 3 * q + a if coordinate else 3 * a + q] += R[j, a, p]


@njit(cache=True)
def rigidity_block_jacobian(R, j, k, coordinate, jac):
    """(9, 18) Jacobian of R_kᵀR_j − I (Eq. 7) over [R_j | R_k], layouts as `rotation_block_jacobian`."""
    jac[:] = 0.0
    for a in range(3):
        for b in range(3):
            for c in range(3):
                jac[3 * a + b, 3 * b + c if coordinate else 3 * c + b] += R[k, c, a]           # d/dR_j[c, b]
                jac[3 * a + b, 9 + (3 * a + c if coordinate else 3 * c + a)] += R[j, c, b]     # d/dR_k[c, a]


@njit(cache=True, inline="always")
def _add_block(data, grad, pos, jac, res, offset, a, b, w, hessian):
    """Add w Jᵀr to `grad` and w JᵀJ to the matrix entries `data[pos]` for one block `jac` of residuals
    res[offset : offset + rows]: its columns are node a's 9 R unknowns, then node b's when it has 18."""
    rows, cols = jac.shape
    for u in range(cols):
        gu = 0.0
        for r in range(rows):
            gu += jac[r, u] * res[offset + r]
        node = a if u < 9 else b
        grad[12 * node + (u % 9)] += w * gu
        if not hessian:
            continue
        for v in range(cols):
            s = 0.0
            for r in range(rows):
                s += jac[r, u] * jac[r, v]
            data[pos[u, v]] += w * s


@njit(cache=True)
def _add_rotation(data, grad, rot_pos, R, r_rot, w, hessian):
    jac = np.zeros((6, 9))
    for j in range(R.shape[0]):
        rotation_block_jacobian(R, j, False, jac)
        _add_block(data, grad, rot_pos[j], jac, r_rot, 6 * j, j, j, w, hessian)


@njit(cache=True)
def _add_rigidity(data, grad, rig_pos, bridges, R, r_rig, w, hessian):
    jac = np.zeros((9, 18))
    for e in range(bridges.shape[0]):
        j = bridges[e, 0]
        k = bridges[e, 1]
        rigidity_block_jacobian(R, j, k, False, jac)
        _add_block(data, grad, rig_pos[e], jac, r_rig, 9 * e, j, k, w, hessian)
