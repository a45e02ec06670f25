"""The Gauss-Newton matrix H of the fast path, as an operator on the coordinate layout.

Vectors use the *coordinate layout*: node j owns y[12 j : 12 j + 12] = [R_jᵀ row-major (9), t_j (3)], i.e.
y[3 (4 j + b) + a] holds R_j[a, b] (b < 3) or t_j[a] (b = 3). Read as a (4N, 3) array, column a is coordinate
a's 4N unknowns, so the linear terms (E_reg, E_con and E_rig's gap, Eq. 4, 5, 7) act as K @ Y
(`coordinate_split.py`). The node blocks of E_rot (Eq. 3) and the bridge blocks of E_rig's R_kᵀR_j − I (Eq. 7)
are dense and added on top:

    H = (K ⊗ I₃) + blockdiag_j(B_rot,j) + Σ_bridges B_rig,e + λ diag(H).

The products are compiled with fused multiply-adds (numba's fastmath "contract" alone: no reordering, one
rounding per multiply-add instead of two): they are most of a CG iteration's instructions.
"""
from __future__ import annotations

import numpy as np

from ...jit import njit
from ..normal_equations import rigidity_block_jacobian


def to_coordinate_layout(v: np.ndarray) -> np.ndarray:
    """(N, 12) solver layout [R row-major, t] → flat coordinate layout [Rᵀ row-major, t]."""
    v = v.reshape(-1, 12)
    out = np.empty_like(v)
    out[:, :9] = v[:, :9].reshape(-1, 3, 3).transpose(0, 2, 1).reshape(-1, 9)
    out[:, 9:] = v[:, 9:]
    return out.reshape(-1)


def from_coordinate_layout(y: np.ndarray) -> np.ndarray:
    """Inverse of `to_coordinate_layout`, returning (N, 12)."""
    return to_coordinate_layout(y).reshape(-1, 12)  # transposing the R part is its own inverse


@njit(cache=True)
def _gram(jac, w, out):
    """out = w jacᵀ jac."""
    for u in range(jac.shape[1]):
        for v in range(u, jac.shape[1]):
            s = 0.0
            for r in range(jac.shape[0]):
                s += jac[r, u] * jac[r, v]
            out[u, v] = w * s
            out[v, u] = w * s


@njit(cache=True, fastmath={"contract"})
def local_blocks(R, bridges, w_rot, w_rig, rot_out, rig_out):
    """Gauss-Newton blocks JᵀJ of E_rot per node (N, 9, 9) and of E_rig's R_kᵀR_j − I per bridge
    (B, 18, 18, [R_j | R_k]), in the coordinate layout (R entry (a, b) at 3 b + a).

    E_rot's block in closed form: with c_b the columns of R_j (contiguous in this layout), the 3×3
    block (b, b') is c_b' c_bᵀ for b ≠ b' and 4 c_b c_bᵀ + Σ_{q≠b} c_q c_qᵀ on the diagonal. The block is
    symmetric: each entry below the diagonal is computed once and mirrored.
    """
    for j in range(R.shape[0]):
        out = rot_out[j]
        for b in range(3):
            for bb in range(b):
                for a in range(3):
                    for aa in range(3):
                        v = w_rot * R[j, a, bb] * R[j, aa, b]
                        out[3 * b + a, 3 * bb + aa] = v
                        out[3 * bb + aa, 3 * b + a] = v
            for a in range(3):
                for aa in range(a + 1):
                    s = 3.0 * R[j, a, b] * R[j, aa, b]
                    for q in range(3):
                        s += R[j, a, q] * R[j, aa, q]
                    out[3 * b + a, 3 * b + aa] = w_rot * s
                    out[3 * b + aa, 3 * b + a] = w_rot * s
    jr = np.zeros((9, 18))
    for e in range(bridges.shape[0]):
        rigidity_block_jacobian(R, bridges[e, 0], bridges[e, 1], True, jr)
        _gram(jr, w_rig, rig_out[e])


@njit(cache=True)
def stretch_curvature(R, w_rot, rot_out):
    """Add to E_rot's Gauss-Newton blocks (N, 9, 9) the positive part of its residuals' own curvature
    (ours). E_rot's Hessian is w_rot (JᵀJ + Σ_r s_r ∇²s_r): for s = c_b·c_b − 1 the second term is
    2 s I₃ on column c_b, for s = c_b·c_b' (b ≠ b') s I₃ across the two columns. Gauss-Newton drops it;
    where a column is stretched (s > 0) that is curvature the model misses, so its steps overshoot and
    shrink by λ, and each frame crawls to the minimum (4.2 steps per frame on the walk at 256 nodes,
    3.1 with this). The diagonal part, kept where positive, leaves the system positive definite; the
    cross terms, indefinite, are left out."""
    for j in range(R.shape[0]):
        for b in range(3):
            s = R[j, 0, b] * R[j, 0, b] + R[j, 1, b] * R[j, 1, b] + R[j, 2, b] * R[j, 2, b] - 1.0
            if s > 0.0:
                for a in range(3):
                    rot_out[j, 3 * b + a, 3 * b + a] += 2.0 * w_rot * s


@njit(cache=True, fastmath={"contract"})
def hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, y, out):
    """out = H y (see the module docstring), as (K_σ ⊗ I₃) y + `local_times`; K in 4 × 4 node blocks
    (`CoordinateSplit`: block row pointers, block columns, blocks (B, 16) row-major)."""
    for i in range(kp.shape[0] - 1):
        o = 12 * i
        s = block_row(kp, ki, kx, i, y, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        for u in range(12):
            out[o + u] = shift[o + u] * y[o + u] - s[u]
    local_times(rot, rig, bridges, damp, shift, y, out)


@njit(cache=True, inline="always", fastmath={"contract"})
def _block_row_times(l, o, y, j):
    """Row o of a 4 × 4 block (l[4 o : 4 o + 4]) times a node's 12 coordinate-layout entries y[j : j + 12]:
    the row's three coordinates."""
    a, b, c, d = l[4 * o], l[4 * o + 1], l[4 * o + 2], l[4 * o + 3]
    return (a * y[j] + b * y[j + 3] + c * y[j + 6] + d * y[j + 9],
            a * y[j + 1] + b * y[j + 4] + c * y[j + 7] + d * y[j + 10],
            a * y[j + 2] + b * y[j + 5] + c * y[j + 8] + d * y[j + 11])


@njit(cache=True, fastmath={"contract"})
def block_row(ptr, col, blocks, k, y, s, skip=-1):
    """s − Σ_q blocks[q] y_col[q] over block row k of a matrix in 4 × 4 node blocks (row pointers `ptr`, block
    columns `col`, blocks (B, 16) row-major), for one node's 12 coordinate-layout entries: s and the result are
    12-tuples (unknown b's coordinate a at 3 b + a), y_j is y[12 j : 12 j + 12]; the block in column `skip` left
    out. The entries are scalars: numba keeps scalars in registers but not a small array."""
    s00, s01, s02, s10, s11, s12, s20, s21, s22, s30, s31, s32 = s
    for q in range(ptr[k], ptr[k + 1]):
        if col[q] == skip:
            continue
        j = 12 * col[q]
        l = blocks[q]
        t0, t1, t2 = _block_row_times(l, 0, y, j)
        s00, s01, s02 = s00 - t0, s01 - t1, s02 - t2
        t0, t1, t2 = _block_row_times(l, 1, y, j)
        s10, s11, s12 = s10 - t0, s11 - t1, s12 - t2
        t0, t1, t2 = _block_row_times(l, 2, y, j)
        s20, s21, s22 = s20 - t0, s21 - t1, s22 - t2
        t0, t1, t2 = _block_row_times(l, 3, y, j)
        s30, s31, s32 = s30 - t0, s31 - t1, s32 - t2
    return s00, s01, s02, s10, s11, s12, s20, s21, s22, s30, s31, s32


@njit(cache=True, fastmath={"contract"})
def off_diagonal_times(kp, ki, kx, rig, bridges, y, base, out):
    """out = base + (H − blockdiag_j H_jj) y: K's blocks between different nodes and the bridges' cross blocks.
    For y = H_jj⁻¹ r node by node (a node solve) H y = r + that, so `base` = r gives H y without the node
    blocks' share of the product."""
    for i in range(kp.shape[0] - 1):
        o = 12 * i
        s = block_row(kp, ki, kx, i, y, (-base[o], -base[o + 1], -base[o + 2], -base[o + 3], -base[o + 4],
                                         -base[o + 5], -base[o + 6], -base[o + 7], -base[o + 8], -base[o + 9],
                                         -base[o + 10], -base[o + 11]), i)
        for u in range(12):
            out[o + u] = -s[u]
    for e in range(bridges.shape[0]):
        oj = 12 * bridges[e, 0]
        ok = 12 * bridges[e, 1]
        for u in range(9):
            a = 0.0
            b = 0.0
            for v in range(9):
                a += rig[e, u, 9 + v] * y[ok + v]
                b += rig[e, 9 + u, v] * y[oj + v]
            out[oj + u] += a
            out[ok + u] += b


@njit(cache=True, fastmath={"contract"})
def local_times(rot, rig, bridges, damp, shift, y, out):
    """out += (H − K_σ ⊗ I₃) y: the node and bridge blocks, the damping, minus the shift σ. No graph-wide
    coupling, so after a coordinate solve z = S r the residual r − H z costs only this."""
    for i in range(y.shape[0]):
        out[i] += (damp[i] - shift[i]) * y[i]
    for j in range(rot.shape[0]):
        o = 12 * j
        for u in range(9):
            s = 0.0
            for v in range(9):
                s += rot[j, u, v] * y[o + v]
            out[o + u] += s
    for e in range(bridges.shape[0]):
        oj = 12 * bridges[e, 0]
        ok = 12 * bridges[e, 1]
        for u in range(18):
            s = 0.0
            for v in range(9):
                s += rig[e, u, v] * y[oj + v] + rig[e, u, 9 + v] * y[ok + v]
            if u < 9:
                out[oj + u] += s
            else:
                out[ok + u - 9] += s

