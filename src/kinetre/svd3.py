"""The singular value decomposition of many 3 × 3 matrices at once, and their determinants.

An export factors every graph node's R_j in every frame (hundreds of thousands of 3 × 3 matrices for a long
take); LAPACK's batched SVD pays a general routine's setup per matrix, which dominates at this size. One-sided
Jacobi (Hestenes) orthogonalises the columns of A by plane rotations V, so A V = U Σ with U's columns the
normalised columns of A V: a few sweeps reach round-off.
"""
from __future__ import annotations

import numpy as np

from .jit import njit

_PAIRS = ((0, 1), (0, 2), (1, 2))


def svd3(matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, s, vt) of (..., 3, 3) matrices as `np.linalg.svd` returns them: matrices = u @ diag(s) @ vt,
    u and vt orthogonal, s (..., 3) non-negative and descending.

    >>> u, s, vt = svd3(np.diag([1.0, 3.0, 2.0]))
    >>> s
    array([3., 2., 1.])
    """
    m = np.asarray(matrices, dtype=np.float64)
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"svd3 takes (..., 3, 3) matrices, got shape {m.shape}")
    flat = np.ascontiguousarray(m.reshape(-1, 3, 3))
    u, s, vt = np.empty_like(flat), np.empty((len(flat), 3)), np.empty_like(flat)
    _svd3(flat, u, s, vt)
    return u.reshape(m.shape), s.reshape(m.shape[:-1]), vt.reshape(m.shape)


def det3(matrices: np.ndarray) -> np.ndarray:
    """(...) determinants of (..., 3, 3) matrices, by the rule of Sarrus (elementwise, no LAPACK call per
    matrix)."""
    a = np.asarray(matrices, dtype=np.float64)
    return (a[..., 0, 0] * (a[..., 1, 1] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 1])
            - a[..., 0, 1] * (a[..., 1, 0] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 0])
            + a[..., 0, 2] * (a[..., 1, 0] * a[..., 2, 1] - a[..., 1, 1] * a[..., 2, 0]))


@njit(cache=True)
def _svd3(m, u_out, s_out, vt_out):
    a = np.empty((3, 3))
    v = np.empty((3, 3))
    norms = np.empty(3)
    for k in range(m.shape[0]):
        for i in range(3):
            for j in range(3):
                a[i, j] = m[k, i, j]
                v[i, j] = 1.0 if i == j else 0.0
        for _ in range(30):  # quadratic convergence: 3-5 sweeps in practice
            rotated = False
            for pair in _PAIRS:
                p, q = pair
                alpha = a[0, p] * a[0, p] + a[1, p] * a[1, p] + a[2, p] * a[2, p]
                beta = a[0, q] * a[0, q] + a[1, q] * a[1, q] + a[2, q] * a[2, q]
                gamma = a[0, p] * a[0, q] + a[1, p] * a[1, q] + a[2, p] * a[2, q]
                if abs(gamma) <= 1e-15 * np.sqrt(alpha * beta) or gamma == 0.0:
                    continue
                rotated = True
                # the rotation that makes columns p and q orthogonal, by its smaller angle
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + np.sqrt(1.0 + zeta * zeta))
                c = 1.0 / np.sqrt(1.0 + t * t)
                s = c * t
                for i in range(3):
                    ap, aq = a[i, p], a[i, q]
                    a[i, p], a[i, q] = c * ap - s * aq, s * ap + c * aq
                    vp, vq = v[i, p], v[i, q]
                    v[i, p], v[i, q] = c * vp - s * vq, s * vp + c * vq
            if not rotated:
                break
        for j in range(3):
            norms[j] = np.sqrt(a[0, j] * a[0, j] + a[1, j] * a[1, j] + a[2, j] * a[2, j])
        # descending order of the three norms, without an allocating argsort per matrix
        o0, o1, o2 = 0, 1, 2
        if norms[o0] < norms[o1]:
            o0, o1 = o1, o0
        if norms[o1] < norms[o2]:
            o1, o2 = o2, o1
        if norms[o0] < norms[o1]:
            o0, o1 = o1, o0
        top = norms[o0]
        for r in range(3):
            j = o0 if r == 0 else (o1 if r == 1 else o2)
            s_out[k, r] = norms[j]
            for i in range(3):
                vt_out[k, r, i] = v[i, j]
                # a column at round-off of the largest carries no direction: completed below
                u_out[k, i, r] = a[i, j] / norms[j] if norms[j] > 1e-14 * top and norms[j] > 0.0 else np.nan
        _complete(u_out[k])


@njit(cache=True)
def _complete(u):
    """Fill the NaN columns of u (3, 3), which come last, so u is orthogonal: from the cross product of the
    other two, and a rank-one or zero matrix's from any perpendicular direction."""
    if np.isnan(u[0, 0]):
        for i in range(3):
            for j in range(3):
                u[i, j] = 1.0 if i == j else 0.0
        return
    if np.isnan(u[0, 1]):
        # the coordinate axis least along column 0, made perpendicular to it
        axis = 0
        for i in range(1, 3):
            if abs(u[i, 0]) < abs(u[axis, 0]):
                axis = i
        d = u[axis, 0]
        n = 0.0
        for i in range(3):
            u[i, 1] = (1.0 if i == axis else 0.0) - d * u[i, 0]
            n += u[i, 1] * u[i, 1]
        n = np.sqrt(n)
        for i in range(3):
            u[i, 1] /= n
    if np.isnan(u[0, 2]):
        u[0, 2] = u[1, 0] * u[2, 1] - u[2, 0] * u[1, 1]
        u[1, 2] = u[2, 0] * u[0, 1] - u[0, 0] * u[2, 1]
        u[2, 2] = u[0, 0] * u[1, 1] - u[1, 0] * u[0, 1]
