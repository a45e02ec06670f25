"""Preconditioned conjugate gradients on the Gauss-Newton system, in numba.

Vectors here use the *coordinate layout*: node j owns y[12 j : 12 j + 12] = [R_jᵀ row-major (9), t_j (3)],
i.e. y[3 (4 j + b) + a] holds R_j[a, b] (b < 3) or t_j[a] (b = 3). Read as a (4N, 3) array, column a is
coordinate a's 4N unknowns, so the linear terms act as K @ Y (`coordinate_split.py`). Node-local
blocks (E_rot, Eq. 3) and bridge blocks (E_rig's R_kᵀR_j − I, Eq. 7) are dense and added on top:

    H = (K ⊗ I₃) + blockdiag_j(B_rot,j) + Σ_bridges B_rig,e + λ diag(H).

Preconditioners (see `_precondition`): the coordinate solve S = (K + σ I_R)⁻¹ per coordinate (one sparse
factor per tracked set in 4 × 4 node blocks, three right-hand sides), exact per-node 12×12 blocks B (block Jacobi), and their
symmetric multiplicative combinations S · B · S (two-level: the factor carries the graph-wide coupling,
the node blocks the rotation stiffness the shift σ only averages) and B · S · B (v-cycle: one pair of
triangular solves per application instead of two, as many CG iterations at 256 nodes and two skeletons,
twice as many at 512). The default, the half cycle (ours), applies B then S, one pair of triangular
solves with H z for free, to the first CG iteration only: on the walk most Gauss-Newton steps need no
more (1.1 per step), and a step that does restarts CG with the symmetric two-level form, since the half
cycle is not symmetric (256 nodes, two skeletons: 1.87 against 2.17 CPU ms per frame). Where such a
product loses definiteness (far from rotations) CG restarts with the additive S + B. Since K_σ S r = r,
the residual after a coordinate solve needs only the node and bridge blocks (`_after_coordinate_solve`),
not a pass over K. A coarse space of region-affine motions (`coarse_space.py`) can join the half cycle, the
two-level (multiplicatively) and block Jacobi (additively).
"""
from __future__ import annotations

import numpy as np

from ..jit import njit
from .coarse_space import coarse_add
from .normal_equations import rigidity_block_jacobian

COORDINATE, BLOCK_JACOBI, TWO_LEVEL, ADDITIVE, V_CYCLE, HALF_CYCLE = 0, 1, 2, 3, 4, 5


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


@njit(cache=True)
def local_blocks(R, bridges, w_rot, w_rig, rot_out, rig_out):
    """Gauss-Newton blocks JᵀJ of E_rot per node (N, 9, 9) and of E_rig's R_kᵀR_j − I per bridge
    (B, 18, 18, [R_j | R_k]), in the coordinate layout (R entry (a, b) at 3 b + a).

    E_rot's block in closed form: with c_b the columns of R_j (contiguous in this layout), the 3×3
    block (b, b') is c_b' c_bᵀ for b ≠ b' and 4 c_b c_bᵀ + Σ_{q≠b} c_q c_qᵀ on the diagonal.
    """
    for j in range(R.shape[0]):
        out = rot_out[j]
        for b in range(3):
            for bb in range(3):
                for a in range(3):
                    for aa in range(3):
                        if b != bb:
                            out[3 * b + a, 3 * bb + aa] = w_rot * R[j, a, bb] * R[j, aa, b]
                        else:
                            s = 3.0 * R[j, a, b] * R[j, aa, b]
                            for q in range(3):
                                s += R[j, a, q] * R[j, aa, q]
                            out[3 * b + a, 3 * b + aa] = w_rot * s
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


@njit(cache=True)
def _hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, y, out):
    """out = H y (see the module docstring), as (K_σ ⊗ I₃) y + `_local_times`; K in 4 × 4 node blocks
    (`CoordinateSplit`: block row pointers, block columns, blocks (B, 16) row-major)."""
    for i in range(kp.shape[0] - 1):
        o = 12 * i
        s = _block_row(kp, ki, kx, i, y, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        for u in range(12):
            out[o + u] = shift[o + u] * y[o + u] - s[u]
    _local_times(rot, rig, bridges, damp, shift, y, out)


@njit(cache=True)
def _block_row(ptr, col, blocks, k, y, s):
    """s − Σ_q blocks[q] y_col[q] over block row k of a matrix in 4 × 4 node blocks (row pointers `ptr`, block
    columns `col`, blocks (B, 16) row-major), for one node's 12 coordinate-layout entries: s and the result are
    12-tuples (unknown b's coordinate a at 3 b + a), y_j is y[12 j : 12 j + 12]. The entries are scalars:
    numba keeps scalars in registers but not a small array (a loop over a (4, 3) array: 1.3-1.6× the time)."""
    s00, s01, s02, s10, s11, s12, s20, s21, s22, s30, s31, s32 = s
    for q in range(ptr[k], ptr[k + 1]):
        j = 12 * col[q]
        l = blocks[q]
        w00, w01, w02 = y[j], y[j + 1], y[j + 2]
        w10, w11, w12 = y[j + 3], y[j + 4], y[j + 5]
        w20, w21, w22 = y[j + 6], y[j + 7], y[j + 8]
        w30, w31, w32 = y[j + 9], y[j + 10], y[j + 11]
        s00 -= l[0] * w00 + l[1] * w10 + l[2] * w20 + l[3] * w30
        s01 -= l[0] * w01 + l[1] * w11 + l[2] * w21 + l[3] * w31
        s02 -= l[0] * w02 + l[1] * w12 + l[2] * w22 + l[3] * w32
        s10 -= l[4] * w00 + l[5] * w10 + l[6] * w20 + l[7] * w30
        s11 -= l[4] * w01 + l[5] * w11 + l[6] * w21 + l[7] * w31
        s12 -= l[4] * w02 + l[5] * w12 + l[6] * w22 + l[7] * w32
        s20 -= l[8] * w00 + l[9] * w10 + l[10] * w20 + l[11] * w30
        s21 -= l[8] * w01 + l[9] * w11 + l[10] * w21 + l[11] * w31
        s22 -= l[8] * w02 + l[9] * w12 + l[10] * w22 + l[11] * w32
        s30 -= l[12] * w00 + l[13] * w10 + l[14] * w20 + l[15] * w30
        s31 -= l[12] * w01 + l[13] * w11 + l[14] * w21 + l[15] * w31
        s32 -= l[12] * w02 + l[13] * w12 + l[14] * w22 + l[15] * w32
    return s00, s01, s02, s10, s11, s12, s20, s21, s22, s30, s31, s32


@njit(cache=True)
def _local_times(rot, rig, bridges, damp, shift, y, out):
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


@njit(cache=True)
def node_factors(k_blocks, rot, rig, bridges, damp, out):
    """Factor H's diagonal 12×12 node blocks (N, 4, 4 `k_blocks`: K's diagonal blocks) into `out` (N, 12, 12).

    A node's t unknowns meet only K (diagonal per coordinate: k_tt I₃ + damping) and, through K, its
    own R, so they are eliminated first: out[:9, :9] holds the Cholesky factor of the 9×9 Schur
    complement S = A − C D⁻¹ Cᵀ (reciprocal diagonal), out[9 + a, 9 + a] = 1 / D_a and out[9, b] = K[b, 3].
    Only S's lower triangle is assembled: the factorisation reads no more (512 nodes: 145-170 against 180-200 µs).
    """
    n = rot.shape[0]
    for j in range(n):
        a = out[j]
        for u in range(9):
            for v in range(u + 1):
                a[u, v] = rot[j, u, v]
    for e in range(bridges.shape[0]):
        for s in range(2):
            a = out[bridges[e, s]]
            for u in range(9):
                for v in range(u + 1):
                    a[u, v] += rig[e, 9 * s + u, 9 * s + v]
    for j in range(n):
        a = out[j]
        kb = k_blocks[j]
        o = 12 * j
        for c in range(3):
            a[9 + c, 9 + c] = 1.0 / (kb[3, 3] + damp[o + 9 + c])
            a[9, c] = kb[c, 3]
        for b in range(3):
            for bb in range(b + 1):
                kk = kb[b, bb]
                kt = kb[b, 3] * kb[bb, 3]
                for c in range(3):
                    a[3 * b + c, 3 * bb + c] += kk - kt * a[9 + c, 9 + c]
        for u in range(9):
            a[u, u] += damp[o + u]
        for c in range(9):
            d = a[c, c]
            for k in range(c):
                d -= a[c, k] * a[c, k]
            d = np.sqrt(d) if d > 0.0 else 1e-150
            a[c, c] = 1.0 / d  # reciprocals on the diagonal: the solves multiply
            for r in range(c + 1, 9):
                s = a[r, c]
                for k in range(c):
                    s -= a[r, k] * a[c, k]
                a[r, c] = s * a[c, c]


@njit(cache=True)
def _node_solve(factors, r, out):
    """out = blockdiag(node blocks)⁻¹ r with the factors of `node_factors`."""
    z = np.empty(9)
    for j in range(factors.shape[0]):
        a = factors[j]
        o = 12 * j
        for c in range(9):  # forward, on f − C D⁻¹ h
            s = r[o + c] - a[9, c // 3] * r[o + 9 + c % 3] * a[9 + c % 3, 9 + c % 3]
            for k in range(c):
                s -= a[c, k] * z[k]
            z[c] = s * a[c, c]
        for c in range(8, -1, -1):
            s = z[c]
            for k in range(c + 1, 9):
                s -= a[k, c] * z[k]
            z[c] = s * a[c, c]
            out[o + c] = z[c]
        for c in range(3):  # t = D⁻¹ (h − Cᵀ u)
            out[o + 9 + c] = (r[o + 9 + c] - a[9, 0] * z[c] - a[9, 1] * z[3 + c] - a[9, 2] * z[6 + c]) \
                * a[9 + c, 9 + c]


@njit(cache=True)
def _coordinate_solve(fac, r, out, work):
    """out = (K_σ ⊗ I₃)⁻¹ r with the block Cholesky factor of `CoordinateSplit._factor`: L w = r block row by
    block row (in elimination order, w in `work`), then Lᵀ v = w from the last, scattering along L's rows (one
    triangle read twice rather than two once: it stays in cache). Node k's 12 entries, unknown b's coordinate a
    as s_ba, are scalars (see `_block_row`)."""
    ptr, col, low, inv, node, _ = fac
    for k in range(ptr.shape[0] - 1):
        o = 12 * node[k]
        s00, s01, s02, s10, s11, s12, s20, s21, s22, s30, s31, s32 = _block_row(
            ptr, col, low, k, work, (r[o], r[o + 1], r[o + 2], r[o + 3], r[o + 4], r[o + 5], r[o + 6], r[o + 7],
                                     r[o + 8], r[o + 9], r[o + 10], r[o + 11]))
        d = inv[k]
        o = 12 * k
        work[o] = d[0] * s00
        work[o + 1] = d[0] * s01
        work[o + 2] = d[0] * s02
        work[o + 3] = d[4] * s00 + d[5] * s10
        work[o + 4] = d[4] * s01 + d[5] * s11
        work[o + 5] = d[4] * s02 + d[5] * s12
        work[o + 6] = d[8] * s00 + d[9] * s10 + d[10] * s20
        work[o + 7] = d[8] * s01 + d[9] * s11 + d[10] * s21
        work[o + 8] = d[8] * s02 + d[9] * s12 + d[10] * s22
        work[o + 9] = d[12] * s00 + d[13] * s10 + d[14] * s20 + d[15] * s30
        work[o + 10] = d[12] * s01 + d[13] * s11 + d[14] * s21 + d[15] * s31
        work[o + 11] = d[12] * s02 + d[13] * s12 + d[14] * s22 + d[15] * s32
    for k in range(ptr.shape[0] - 2, -1, -1):
        d = inv[k]
        o = 12 * k
        w00, w01, w02 = work[o], work[o + 1], work[o + 2]
        w10, w11, w12 = work[o + 3], work[o + 4], work[o + 5]
        w20, w21, w22 = work[o + 6], work[o + 7], work[o + 8]
        w30, w31, w32 = work[o + 9], work[o + 10], work[o + 11]
        s00 = d[0] * w00 + d[4] * w10 + d[8] * w20 + d[12] * w30
        s01 = d[0] * w01 + d[4] * w11 + d[8] * w21 + d[12] * w31
        s02 = d[0] * w02 + d[4] * w12 + d[8] * w22 + d[12] * w32
        s10 = d[5] * w10 + d[9] * w20 + d[13] * w30
        s11 = d[5] * w11 + d[9] * w21 + d[13] * w31
        s12 = d[5] * w12 + d[9] * w22 + d[13] * w32
        s20 = d[10] * w20 + d[14] * w30
        s21 = d[10] * w21 + d[14] * w31
        s22 = d[10] * w22 + d[14] * w32
        s30 = d[15] * w30
        s31 = d[15] * w31
        s32 = d[15] * w32
        for q in range(ptr[k], ptr[k + 1]):
            j = 12 * col[q]
            l = low[q]
            work[j] -= l[0] * s00 + l[4] * s10 + l[8] * s20 + l[12] * s30
            work[j + 1] -= l[0] * s01 + l[4] * s11 + l[8] * s21 + l[12] * s31
            work[j + 2] -= l[0] * s02 + l[4] * s12 + l[8] * s22 + l[12] * s32
            work[j + 3] -= l[1] * s00 + l[5] * s10 + l[9] * s20 + l[13] * s30
            work[j + 4] -= l[1] * s01 + l[5] * s11 + l[9] * s21 + l[13] * s31
            work[j + 5] -= l[1] * s02 + l[5] * s12 + l[9] * s22 + l[13] * s32
            work[j + 6] -= l[2] * s00 + l[6] * s10 + l[10] * s20 + l[14] * s30
            work[j + 7] -= l[2] * s01 + l[6] * s11 + l[10] * s21 + l[14] * s31
            work[j + 8] -= l[2] * s02 + l[6] * s12 + l[10] * s22 + l[14] * s32
            work[j + 9] -= l[3] * s00 + l[7] * s10 + l[11] * s20 + l[15] * s30
            work[j + 10] -= l[3] * s01 + l[7] * s11 + l[11] * s21 + l[15] * s31
            work[j + 11] -= l[3] * s02 + l[7] * s12 + l[11] * s22 + l[15] * s32
        o = 12 * node[k]
        out[o], out[o + 1], out[o + 2] = s00, s01, s02
        out[o + 3], out[o + 4], out[o + 5] = s10, s11, s12
        out[o + 6], out[o + 7], out[o + 8] = s20, s21, s22
        out[o + 9], out[o + 10], out[o + 11] = s30, s31, s32



@njit(cache=True)
def _precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz, t1, t2, work):
    """z = M⁻¹ r for the chosen preconditioner (t1, t2, work: scratch). Returns whether it also wrote
    hz = H z (two-level: it comes almost free, see below), sparing CG its own product with H.

    With a coarse space (`coarse` = (factor, region, offsets) of `coarse_space.py`, factor (0, 0): none) the
    half cycle and the two-level start with the coarse correction z = C r and go on from r − H z; the
    two-level also ends with one (C, two-level, C: symmetric)."""
    shift = fac[5]
    gfac, region, offsets = coarse
    if kind == BLOCK_JACOBI:  # with a coarse space additively: z = B r + C r (symmetric)
        _node_solve(node_fac, r, z)
        if gfac.shape[0]:
            coarse_add(gfac, region, offsets, r, z)
        return False
    if kind == HALF_CYCLE:  # z ← B r, z ← z + S (r − H z): one coordinate solve, and H z comes free
        if gfac.shape[0]:  # z ← C r, z ← z + B (r − H z) first
            z[:] = 0.0
            coarse_add(gfac, region, offsets, r, z)
            _hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, z, hz)
            for i in range(r.shape[0]):
                t1[i] = r[i] - hz[i]
            _node_solve(node_fac, t1, t2)
            for i in range(r.shape[0]):
                z[i] += t2[i]
        else:
            _node_solve(node_fac, r, z)
        _hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, z, hz)
        _coordinate_step(fac, rot, rig, bridges, damp, r, z, hz, t1, t2, work)
        return True
    if kind == V_CYCLE:  # z ← B r, z ← z + S (r − H z), z ← z + B (r − H z)
        _node_solve(node_fac, r, z)
        _hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, z, t1)
        for i in range(r.shape[0]):
            t1[i] = r[i] - t1[i]
        _coordinate_solve(fac, t1, t2, work)
        _after_coordinate_solve(rot, rig, bridges, damp, shift, z, t1, t2)
        _node_solve(node_fac, t1, t2)
        for i in range(r.shape[0]):
            z[i] += t2[i]
        return False
    if kind == TWO_LEVEL and gfac.shape[0]:  # C, the two-level on what is left, C again
        zc = np.zeros(r.shape[0])
        coarse_add(gfac, region, offsets, r, zc)
        hc = np.empty(r.shape[0])
        _hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, zc, hc)
        rest = r - hc
        _two_level(fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, rest, z, hz, t1, t2, work)
        for i in range(r.shape[0]):
            z[i] += zc[i]
            rest[i] = r[i] - hz[i] - hc[i]
        coarse_add(gfac, region, offsets, rest, z)
        return False
    if kind == TWO_LEVEL:
        _two_level(fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, r, z, hz, t1, t2, work)
        return True
    _coordinate_solve(fac, r, z, work)
    if kind == ADDITIVE:  # z = S r + B r: positive definite whatever the pose
        _node_solve(node_fac, r, t2)
        for i in range(r.shape[0]):
            z[i] += t2[i]
    return False


@njit(cache=True)
def _two_level(fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, r, z, hz, t1, t2, work):
    """Symmetric multiplicative: z ← S r, z ← z + B (r − H z), z ← z + S (r − H z); hz ← H z."""
    shift = fac[5]
    _coordinate_solve(fac, r, t2, work)
    z[:] = 0.0
    _after_coordinate_solve(rot, rig, bridges, damp, shift, z, t1, t2)
    _node_solve(node_fac, t1, t2)
    for i in range(r.shape[0]):
        z[i] += t2[i]
    _hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, z, hz)
    _coordinate_step(fac, rot, rig, bridges, damp, r, z, hz, t1, t2, work)


@njit(cache=True)
def _coordinate_step(fac, rot, rig, bridges, damp, r, z, hz, t1, t2, work):
    """z ← z + S (r − H z) given hz = H z, which it keeps equal to H z without a pass over K:
    H (z + t2) = H z + K_σ t2 + (H − K_σ) t2 = hz + (r − hz) + local part."""
    shift = fac[5]
    for i in range(r.shape[0]):
        t1[i] = r[i] - hz[i]
    _coordinate_solve(fac, t1, t2, work)
    for i in range(r.shape[0]):
        z[i] += t2[i]
        hz[i] += t1[i]
    _local_times(rot, rig, bridges, damp, shift, t2, hz)


@njit(cache=True)
def _after_coordinate_solve(rot, rig, bridges, damp, shift, z, residual, step):
    """z += step, residual ← residual − H step, for step = S residual: since K_σ step = residual, that is
    −(H − K_σ ⊗ I₃) step, node-local (no pass over K)."""
    for i in range(z.shape[0]):
        z[i] += step[i]
        residual[i] = 0.0
    _local_times(rot, rig, bridges, damp, shift, step, residual)
    for i in range(z.shape[0]):
        residual[i] = -residual[i]


@njit(cache=True)
def pcg(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, b, max_iterations, tolerance):
    """Solve H x = b approximately from x = 0: stops after `max_iterations` or when ‖r‖ ≤ tolerance ‖b‖.

    Returns (x, iterations, converged): `converged` says the residual reached the tolerance. Every
    iterate lowers the quadratic model ½ xᵀHx − bᵀx, so even one iteration is a descent direction for
    the energy.
    """
    n = b.shape[0]
    x = np.zeros(n)
    r = b.copy()
    z = np.empty(n)
    hz = np.empty(n)
    p = np.empty(n)
    hp = np.empty(n)
    t1 = np.empty(n)
    t2 = np.empty(n)
    work = np.empty(n)
    bnorm = np.sqrt(b @ b)
    if bnorm == 0.0:
        return x, 0, True
    known = _precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz, t1, t2, work)
    p[:] = z
    if known:  # hp = H p without a pass over K: H z from the preconditioner, H p by the same recurrence as p
        hp[:] = hz
    rz = r @ z
    it = 0
    while it < max_iterations:
        if not (rz > 0.0) and (kind == TWO_LEVEL or kind == V_CYCLE or kind == HALF_CYCLE):
            # far from rotations E_rot's blocks outgrow 2 (K + σ I) and the multiplicative form can lose
            # definiteness: restart from x with the additive form, which cannot
            kind = ADDITIVE
            known = _precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz,
                                  t1, t2, work)
            p[:] = z
            rz = r @ z
        if not known:
            _hessian_times(kp, ki, kx, rot, rig, bridges, damp, fac[5], p, hp)
            known = True
        php = p @ hp
        if not (php > 0.0) or not (rz > 0.0):
            break
        alpha = rz / php
        x += alpha * p
        r -= alpha * hp
        it += 1
        if np.sqrt(r @ r) <= tolerance * bnorm or it >= max_iterations:
            break
        if kind == HALF_CYCLE:
            # one iteration did not do: CG needs a symmetric preconditioner, so restart from x with
            # the two-level one
            kind = TWO_LEVEL
            known = _precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz,
                                  t1, t2, work)
            p[:] = z
            if known:
                hp[:] = hz
            rz = r @ z
            continue
        fresh = _precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz, t1, t2, work)
        rz_new = r @ z
        if not (rz_new > 0.0):
            rz = rz_new
            known = False
            continue
        beta = rz_new / rz
        rz = rz_new
        p *= beta
        p += z
        known = fresh
        if known:
            hp *= beta
            hp += hz
    return x, it, np.sqrt(r @ r) <= tolerance * bnorm
