"""Affine transforms as 4 × 4 homogeneous matrices (last row 0 0 0 1, as glTF nodes and joints hold them): the
inverse of a whole stack, by the 3 × 3 block's adjugate. A stacked `np.linalg.inv` makes one LAPACK call per
matrix, and a threaded BLAS synchronises its threads in each: on a busy machine a take's worth of joint
matrices then costs seconds where this costs a millisecond."""
from __future__ import annotations

import numpy as np


def affine_inverse(m: np.ndarray) -> np.ndarray:
    """(..., 4, 4) inverses of the affine (..., 4, 4) matrices `m`: [A t; 0 1]⁻¹ = [A⁻¹  −A⁻¹t; 0 1]."""
    m = np.asarray(m, dtype=np.float64)
    a = m[..., :3, :3]
    adjugate = np.empty_like(a)  # transposed cofactors: A⁻¹ = adj(A) / det(A)
    for i in range(3):
        for j in range(3):
            r0, r1 = [r for r in range(3) if r != j]
            c0, c1 = [c for c in range(3) if c != i]
            sign = 1.0 if (i + j) % 2 == 0 else -1.0
            adjugate[..., i, j] = sign * (a[..., r0, c0] * a[..., r1, c1] - a[..., r0, c1] * a[..., r1, c0])
    det = np.einsum("...j,...j->...", a[..., 0, :], adjugate[..., :, 0])
    inverse_a = adjugate / det[..., None, None]
    out = np.zeros_like(m)
    out[..., :3, :3] = inverse_a
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", inverse_a, m[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out
