"""The preconditioners of the fast path's conjugate gradients (`cg.py`), M⁻¹ ≈ H⁻¹ (`hessian.py`).

Two parts, each cheap where the other is poor:
- the coordinate solve S = (K_σ ⊗ I₃)⁻¹, K_σ = K + σ I_R: one sparse factor per tracked set in 4 × 4 node
  blocks (`coordinate_split.py`), one pair of triangular solves for the three coordinates at once. It
  carries the graph-wide coupling; σ is E_rot's curvature averaged over rotations;
- the node blocks B: H's exact 12×12 diagonal block per node (block Jacobi), which carries the rotation
  stiffness that σ only averages.

They are combined as:
- the two-level S · B · S (symmetric multiplicative);
- the half cycle (ours) B then S: one pair of triangular solves, H z for free; not symmetric, so CG uses
  it for a step's first iteration only, and a step that needs more restarts with the two-level;
- the additive S + B, positive definite whatever the pose: CG restarts with it where a multiplicative
  form loses definiteness (far from rotations).

Since K_σ S r = r, the residual after a coordinate solve needs only the node and bridge blocks
(`after_coordinate_solve`), not a pass over K; likewise, since B's blocks are H's own, H times a node solve's
result needs only the blocks between nodes (`hessian.off_diagonal_times`). A coarse space of region-affine motions (`coarse_space.py`)
joins the half cycle and the two-level multiplicatively. The coordinate solve uses fused multiply-adds like
the products of `hessian.py`.
"""
from __future__ import annotations

import numpy as np

from ...jit import njit
from .coarse_space import coarse_add
from .hessian import block_row, hessian_times, local_times, off_diagonal_times

TWO_LEVEL, ADDITIVE, HALF_CYCLE = 1, 2, 3


# The node blocks' factors are stored lane-major: nodes in chunks of `NODE_LANES`, each entry of a chunk a row of
# NODE_LANES numbers, one per node. Every loop over a chunk's lanes is then one the compiler turns into vector
# instructions (nodes are independent), where a node at a time is a chain of dependent square roots and divisions.
NODE_LANES = 64
# entries per node: S's lower triangle (45, row by row, reciprocals on the diagonal), 1 / D (3), K's t column (3)
_TRIANGLE, _INV_D, _K_T = 0, 45, 48
NODE_ENTRIES = 51


def node_factor_buffer(nodes: int) -> np.ndarray:
    """A buffer for `node_factors` of `nodes` nodes: (chunks, NODE_ENTRIES, NODE_LANES)."""
    return np.zeros(((nodes + NODE_LANES - 1) // NODE_LANES, NODE_ENTRIES, NODE_LANES))


@njit(cache=True, error_model="numpy")
def node_factors(k_blocks, rot, rig, bridges, damp, out):
    """Factor H's diagonal 12×12 node blocks (N, 4, 4 `k_blocks`: K's diagonal blocks) into `out`
    (`node_factor_buffer`).

    A node's t unknowns meet only K (diagonal per coordinate: k_tt I₃ + damping) and, through K, its
    own R, so they are eliminated first: the triangle holds the Cholesky factor of the 9×9 Schur
    complement S = A − C D⁻¹ Cᵀ (reciprocal diagonal), then 1 / D_a and K[b, 3]. Only S's lower triangle
    is assembled: the factorisation reads no more. The lanes past N are identity blocks. (numpy's error model:
    Python's would test every division for zero, which keeps the loops from being vectorised.)
    """
    n = rot.shape[0]
    lanes = out.shape[2]
    s = np.empty(lanes)
    for ch in range(out.shape[0]):
        a = out[ch]
        base = ch * lanes
        used = min(lanes, n - base)
        for u in range(9):
            for v in range(u + 1):
                t = u * (u + 1) // 2 + v
                for ln in range(used):
                    a[t, ln] = rot[base + ln, u, v]
                for ln in range(used, lanes):
                    a[t, ln] = 1.0 if u == v else 0.0
    for e in range(bridges.shape[0]):
        for side in range(2):
            j = bridges[e, side]
            a = out[j // lanes]
            ln = j % lanes
            for u in range(9):
                for v in range(u + 1):
                    a[u * (u + 1) // 2 + v, ln] += rig[e, 9 * side + u, 9 * side + v]
    for ch in range(out.shape[0]):
        a = out[ch]
        base = ch * lanes
        used = min(lanes, n - base)
        for c in range(3):
            for ln in range(used):
                a[_INV_D + c, ln] = 1.0 / (k_blocks[base + ln, 3, 3] + damp[12 * (base + ln) + 9 + c])
                a[_K_T + c, ln] = k_blocks[base + ln, c, 3]
            for ln in range(used, lanes):
                a[_INV_D + c, ln] = 1.0
                a[_K_T + c, ln] = 0.0
        for b in range(3):
            for bb in range(b + 1):
                for c in range(3):
                    u = 3 * b + c
                    t = u * (u + 1) // 2 + 3 * bb + c
                    for ln in range(used):
                        kb = k_blocks[base + ln]
                        kt = kb[b, 3] * kb[bb, 3]
                        a[t, ln] += kb[b, bb] - kt * a[_INV_D + c, ln]
        for u in range(9):
            t = u * (u + 1) // 2 + u
            for ln in range(used):
                a[t, ln] += damp[12 * (base + ln) + u]
        for c in range(9):
            row = c * (c + 1) // 2
            for ln in range(lanes):
                s[ln] = a[row + c, ln]
            for k in range(c):
                for ln in range(lanes):
                    s[ln] -= a[row + k, ln] * a[row + k, ln]
            for ln in range(lanes):
                d = s[ln]
                a[row + c, ln] = 1.0 / (np.sqrt(d) if d > 0.0 else 1e-150)  # reciprocals: the solves multiply
            for r in range(c + 1, 9):
                other = r * (r + 1) // 2
                for ln in range(lanes):
                    s[ln] = a[other + c, ln]
                for k in range(c):
                    for ln in range(lanes):
                        s[ln] -= a[other + k, ln] * a[row + k, ln]
                for ln in range(lanes):
                    a[other + c, ln] = s[ln] * a[row + c, ln]


@njit(cache=True)
def node_solve(factors, r, out):
    """out = blockdiag(node blocks)⁻¹ r with the factors of `node_factors`, a chunk of nodes at a time."""
    lanes = factors.shape[2]
    n = r.shape[0] // 12
    y = np.empty((12, lanes))
    z = np.empty((9, lanes))
    s = np.empty(lanes)
    for ch in range(factors.shape[0]):
        a = factors[ch]
        base = ch * lanes
        used = min(lanes, n - base)
        for ln in range(used):
            for u in range(12):
                y[u, ln] = r[12 * (base + ln) + u]
        for ln in range(used, lanes):
            for u in range(12):
                y[u, ln] = 0.0
        for c in range(9):  # forward, on f − C D⁻¹ h
            row = c * (c + 1) // 2
            for ln in range(lanes):
                s[ln] = y[c, ln] - a[_K_T + c // 3, ln] * y[9 + c % 3, ln] * a[_INV_D + c % 3, ln]
            for k in range(c):
                for ln in range(lanes):
                    s[ln] -= a[row + k, ln] * z[k, ln]
            for ln in range(lanes):
                z[c, ln] = s[ln] * a[row + c, ln]
        for c in range(8, -1, -1):
            for ln in range(lanes):
                s[ln] = z[c, ln]
            for k in range(c + 1, 9):
                t = k * (k + 1) // 2 + c
                for ln in range(lanes):
                    s[ln] -= a[t, ln] * z[k, ln]
            t = c * (c + 1) // 2 + c
            for ln in range(lanes):
                z[c, ln] = s[ln] * a[t, ln]
        for ln in range(used):
            o = 12 * (base + ln)
            for c in range(9):
                out[o + c] = z[c, ln]
            for c in range(3):  # t = D⁻¹ (h − Cᵀ u)
                out[o + 9 + c] = (y[9 + c, ln] - a[_K_T, ln] * z[c, ln] - a[_K_T + 1, ln] * z[3 + c, ln]
                                  - a[_K_T + 2, ln] * z[6 + c, ln]) * a[_INV_D + c, ln]


@njit(cache=True, fastmath={"contract"})
def coordinate_solve(fac, r, out, work):
    """out = (K_σ ⊗ I₃)⁻¹ r with the block Cholesky factor of `CoordinateSplit` (its `frame_data`): L w = r block row by
    block row (in elimination order, w in `work`), then Lᵀ v = w from the last, scattering along L's rows (one
    triangle read twice rather than two once: it stays in cache). Node k's 12 entries, unknown b's coordinate a
    as s_ba, are scalars (see `block_row`)."""
    ptr, col, low, inv, node, _ = fac
    for k in range(ptr.shape[0] - 1):
        o = 12 * node[k]
        s00, s01, s02, s10, s11, s12, s20, s21, s22, s30, s31, s32 = block_row(
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
def precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz, t1, t2, work):
    """z = M⁻¹ r for the chosen preconditioner (t1, t2, work: scratch). Returns whether it also wrote
    hz = H z (two-level: it comes almost free, see below), sparing CG its own product with H.

    With a coarse space (`coarse` = (factor, region, offsets) of `coarse_space.py`, factor (0, 0): none) the
    half cycle and the two-level start with the coarse correction z = C r and go on from r − H z; the
    two-level also ends with one (C, two-level, C: symmetric)."""
    shift = fac[5]
    gfac, region, offsets = coarse
    if kind == HALF_CYCLE:  # z ← B r, z ← z + S (r − H z): one coordinate solve, and H z comes free
        if gfac.shape[0]:  # z ← C r, z ← z + B (r − H z) first
            z[:] = 0.0
            coarse_add(gfac, region, offsets, r, z)
            hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, z, hz)
            for i in range(r.shape[0]):
                t1[i] = r[i] - hz[i]
            node_solve(node_fac, t1, t2)
            for i in range(r.shape[0]):
                z[i] += t2[i]
            # H z = (H z_C + t1) + (H − B) t2 = r + (H − B) t2, B t2 = t1
            off_diagonal_times(kp, ki, kx, rig, bridges, t2, r, hz)
        else:
            node_solve(node_fac, r, z)
            off_diagonal_times(kp, ki, kx, rig, bridges, z, r, hz)  # H z = r + (H − B) z, B z = r
        _coordinate_step(fac, rot, rig, bridges, damp, r, z, hz, t1, t2, work)
        return True
    if kind == TWO_LEVEL and gfac.shape[0]:  # C, the two-level on what is left, C again
        zc = np.zeros(r.shape[0])
        coarse_add(gfac, region, offsets, r, zc)
        hc = np.empty(r.shape[0])
        hessian_times(kp, ki, kx, rot, rig, bridges, damp, shift, zc, hc)
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
    coordinate_solve(fac, r, z, work)  # ADDITIVE: z = S r + B r, positive definite whatever the pose
    node_solve(node_fac, r, t2)
    for i in range(r.shape[0]):
        z[i] += t2[i]
    return False


@njit(cache=True)
def _two_level(fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, r, z, hz, t1, t2, work):
    """Symmetric multiplicative: z ← S r, z ← z + B (r − H z), z ← z + S (r − H z); hz ← H z."""
    shift = fac[5]
    coordinate_solve(fac, r, t2, work)
    z[:] = 0.0
    after_coordinate_solve(rot, rig, bridges, damp, shift, z, t1, t2)
    node_solve(node_fac, t1, t2)
    for i in range(r.shape[0]):
        z[i] += t2[i]
    # H z = (r − t1) + (B t2 + (H − B) t2) = r + (H − B) t2, B t2 = t1
    off_diagonal_times(kp, ki, kx, rig, bridges, t2, r, hz)
    _coordinate_step(fac, rot, rig, bridges, damp, r, z, hz, t1, t2, work)


@njit(cache=True)
def _coordinate_step(fac, rot, rig, bridges, damp, r, z, hz, t1, t2, work):
    """z ← z + S (r − H z) given hz = H z, which it keeps equal to H z without a pass over K:
    H (z + t2) = H z + K_σ t2 + (H − K_σ) t2 = hz + (r − hz) + local part."""
    shift = fac[5]
    for i in range(r.shape[0]):
        t1[i] = r[i] - hz[i]
    coordinate_solve(fac, t1, t2, work)
    for i in range(r.shape[0]):
        z[i] += t2[i]
        hz[i] += t1[i]
    local_times(rot, rig, bridges, damp, shift, t2, hz)


@njit(cache=True)
def after_coordinate_solve(rot, rig, bridges, damp, shift, z, residual, step):
    """z += step, residual ← residual − H step, for step = S residual: since K_σ step = residual, that is
    −(H − K_σ ⊗ I₃) step, node-local (no pass over K)."""
    for i in range(z.shape[0]):
        z[i] += step[i]
        residual[i] = 0.0
    local_times(rot, rig, bridges, damp, shift, step, residual)
    for i in range(z.shape[0]):
        residual[i] = -residual[i]

