"""The fast kernel of the energy (Eq. 8, its terms Eq. 3, 4, 5, 7 as defined in `deform/energy.py`) and its
Gauss-Newton gradient Σ w Jᵀr, in one numba pass over nodes, edges, constraints and bridges: the per-step work
of the fast path. The tests check it against the definitions and the reference Jacobians.

The gradient comes out in the coordinate layout of `hessian.py` (R_j[a, b] at 12 j + 3 b + a).
"""
from __future__ import annotations

import numpy as np

from ...jit import njit
from ..jacobian import ROT_P, ROT_Q


@njit(cache=True)
def energy_gradient(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                    w_rot, w_reg, w_con, w_rig, grad, want_gradient):
    """E (Eq. 8) at x (N, 12); with `want_gradient`, also Σ w Jᵀr into `grad` (12N, overwritten)."""
    n = x.shape[0]
    if want_gradient:
        grad[:] = 0.0
    e_rot = 0.0
    for j in range(n):  # Eq. 3
        o = 12 * j
        for r in range(6):
            p = ROT_P[r]
            q = ROT_Q[r]
            s = x[j, p] * x[j, q] + x[j, 3 + p] * x[j, 3 + q] + x[j, 6 + p] * x[j, 6 + q]
            if p == q:
                s -= 1.0
            e_rot += s * s
            if want_gradient:
                ws = w_rot * s
                for a in range(3):
                    grad[o + 3 * p + a] += ws * x[j, 3 * a + q]
                    grad[o + 3 * q + a] += ws * x[j, 3 * a + p]
    e_reg = 0.0
    for e in range(edges.shape[0]):  # Eq. 4, both directions of each edge
        for d in range(2):
            j = edges[e, d]
            k = edges[e, 1 - d]
            dx = g[k, 0] - g[j, 0]
            dy = g[k, 1] - g[j, 1]
            dz = g[k, 2] - g[j, 2]
            for a in range(3):
                r = (x[j, 3 * a] * dx + x[j, 3 * a + 1] * dy + x[j, 3 * a + 2] * dz
                     - (g[k, a] - g[j, a]) + x[j, 9 + a] - x[k, 9 + a])
                e_reg += r * r
                if want_gradient:
                    wr = w_reg * r
                    grad[12 * j + a] += wr * dx
                    grad[12 * j + 3 + a] += wr * dy
                    grad[12 * j + 6 + a] += wr * dz
                    grad[12 * j + 9 + a] += wr
                    grad[12 * k + 9 + a] -= wr
    e_con = 0.0
    carriers = con_nodes.shape[1]
    offset = np.empty((carriers, 3))  # p_ℓ − g_j per carrier: read by all three coordinates and the gradient
    for c in range(con_nodes.shape[0]):  # Eq. 5
        s = active[c]
        if s == 0.0:
            continue
        for i in range(carriers):
            j = con_nodes[c, i]
            for b in range(3):
                offset[i, b] = con_points[c, b] - g[j, b]
        for a in range(3):
            phi = 0.0
            for i in range(carriers):
                j = con_nodes[c, i]
                phi += con_weights[c, i] * (x[j, 3 * a] * offset[i, 0] + x[j, 3 * a + 1] * offset[i, 1]
                                            + x[j, 3 * a + 2] * offset[i, 2] + g[j, a] + x[j, 9 + a])
            r = s * (phi - targets[c, a])
            e_con += r * r
            if want_gradient:
                wr = w_con * s * r
                for i in range(carriers):
                    o = 12 * con_nodes[c, i] + a
                    wi = wr * con_weights[c, i]
                    grad[o] += wi * offset[i, 0]
                    grad[o + 3] += wi * offset[i, 1]
                    grad[o + 6] += wi * offset[i, 2]
                    grad[o + 9] += wi
    e_rig = 0.0
    for e in range(bridges.shape[0]):  # Eq. 7: R_kᵀ R_j − I and the midpoint gap
        j = bridges[e, 0]
        k = bridges[e, 1]
        for a in range(3):
            for b in range(3):
                s = x[k, a] * x[j, b] + x[k, 3 + a] * x[j, 3 + b] + x[k, 6 + a] * x[j, 6 + b]
                if a == b:
                    s -= 1.0
                e_rig += s * s
                if want_gradient:
                    for c in range(3):
                        grad[12 * j + 3 * b + c] += w_rig * s * x[k, 3 * c + a]
                        grad[12 * k + 3 * a + c] += w_rig * s * x[j, 3 * c + b]
        for a in range(3):
            r = x[j, 9 + a] - x[k, 9 + a] + g[j, a] - g[k, a]
            for b in range(3):
                m = 0.5 * (g[j, b] + g[k, b])
                r += x[j, 3 * a + b] * (m - g[j, b]) - x[k, 3 * a + b] * (m - g[k, b])
            e_rig += r * r
            if want_gradient:
                wr = w_rig * r
                for b in range(3):
                    m = 0.5 * (g[j, b] + g[k, b])
                    grad[12 * j + 3 * b + a] += wr * (m - g[j, b])
                    grad[12 * k + 3 * b + a] -= wr * (m - g[k, b])
                grad[12 * j + 9 + a] += wr
                grad[12 * k + 9 + a] -= wr
    return w_rot * e_rot + w_reg * e_reg + w_con * e_con + w_rig * e_rig
