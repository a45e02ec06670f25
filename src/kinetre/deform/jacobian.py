"""Analytic Jacobians of each energy term, as sparse matrices over the stacked unknowns.

Unknowns: x is (N, 12) flattened, node j owning columns 12 j … 12 j + 11 as
[R_j row-major (9), t_j (3)], so R_j[a, b] is column 12 j + 3 a + b and t_j[a] is 12 j + 9 + a.
Rows follow the residual layouts of `energy.py`. These are the reference the fast assembly in
`normal_equations.py` is tested against (and finite differences test these).
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix

from .constraints import PointConstraints

# Column pairs (p, q) of R behind the 6 rotation residuals, in `rotation_residuals` order.
ROT_PAIRS = ((0, 1), (0, 2), (1, 2), (0, 0), (1, 1), (2, 2))
ROT_P = np.array([p for p, _ in ROT_PAIRS], dtype=np.int64)  # the pairs as arrays, for the kernels
ROT_Q = np.array([q for _, q in ROT_PAIRS], dtype=np.int64)


def r_col(j, a, b):
    return 12 * np.asarray(j) + 3 * a + b


def t_col(j, a):
    return 12 * np.asarray(j) + 9 + a


def _coo(rows, cols, vals, shape):
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=shape).tocsr()


def rotation_jacobian(R: np.ndarray) -> csr_matrix:
    """d(Eq. 3 residuals)/dx: (6N, 12N). d(c_p·c_q)/dR[a, p] = R[a, q] and d/dR[a, q] = R[a, p]."""
    n = len(R)
    j = np.arange(n)
    rows, cols, vals = [], [], []
    for r, (p, q) in enumerate(ROT_PAIRS):
        for a in range(3):
            rows += [6 * j + r, 6 * j + r]
            cols += [r_col(j, a, p), r_col(j, a, q)]
            vals += [R[:, a, q], R[:, a, p]]
    return _coo(rows, cols, vals, (6 * n, 12 * n))


def regularization_jacobian(g: np.ndarray, edges: np.ndarray) -> csr_matrix:
    """d(Eq. 4 residuals)/dx: (6E, 12N), constant: dr_a/dR_j[a, b] = (g_k − g_j)_b, ±1 on t."""
    n = len(g)
    j = np.concatenate([edges[:, 0], edges[:, 1]])
    k = np.concatenate([edges[:, 1], edges[:, 0]])
    e = np.arange(len(j))
    rows, cols, vals = [], [], []
    for a in range(3):
        for b in range(3):
            rows.append(3 * e + a)
            cols.append(r_col(j, a, b))
            vals.append(g[k, b] - g[j, b])
        rows += [3 * e + a, 3 * e + a]
        cols += [t_col(j, a), t_col(k, a)]
        vals += [np.ones(len(e)), -np.ones(len(e))]
    return _coo(rows, cols, vals, (3 * len(e), 12 * n))


def constraint_jacobian(g: np.ndarray, constraints: PointConstraints) -> csr_matrix:
    """d(Eq. 5 residuals)/dx: (3L, 12N), constant: w_i (p − g_i)_b on R_i[a, b], w_i on t_i[a]."""
    n = len(g)
    p, idx, w = constraints.points, constraints.nodes, constraints.weights
    ell = np.arange(len(p))
    rows, cols, vals = [], [], []
    for i in range(idx.shape[1]):
        ni = idx[:, i]
        for a in range(3):
            for b in range(3):
                rows.append(3 * ell + a)
                cols.append(r_col(ni, a, b))
                vals.append(w[:, i] * (p[:, b] - g[ni, b]))
            rows.append(3 * ell + a)
            cols.append(t_col(ni, a))
            vals.append(w[:, i])
    return _coo(rows, cols, vals, (3 * len(p), 12 * n))


def rigidity_jacobian(R: np.ndarray, g: np.ndarray, bridges: np.ndarray) -> csr_matrix:
    """d(Eq. 7 residuals)/dx: (12B, 12N).

    (R_kᵀ R_j)[a, b] = Σ_c R_k[c, a] R_j[c, b]: d/dR_j[c, b] = R_k[c, a], d/dR_k[c, a] = R_j[c, b];
    the midpoint gap is linear like Eq. 4.
    """
    n = len(R)
    j, k = bridges[:, 0], bridges[:, 1]
    e = np.arange(len(j))
    m = 0.5 * (g[j] + g[k])
    rows, cols, vals = [], [], []
    for a in range(3):
        for b in range(3):
            row = 12 * e + 3 * a + b
            for c in range(3):
                rows += [row, row]
                cols += [r_col(j, c, b), r_col(k, c, a)]
                vals += [R[k, c, a], R[j, c, b]]
    for a in range(3):
        row = 12 * e + 9 + a
        for b in range(3):
            rows += [row, row]
            cols += [r_col(j, a, b), r_col(k, a, b)]
            vals += [m[:, b] - g[j, b], -(m[:, b] - g[k, b])]
        rows += [row, row]
        cols += [t_col(j, a), t_col(k, a)]
        vals += [np.ones(len(e)), -np.ones(len(e))]
    return _coo(rows, cols, vals, (12 * len(e), 12 * n))
