"""Preconditioned conjugate gradients on one Gauss-Newton step's system H δ = −∇E (`hessian.py`,
`preconditioner.py`), truncated: a few iterations from δ = 0."""
from __future__ import annotations

import numpy as np

from ...jit import njit
from .hessian import hessian_times
from .preconditioner import ADDITIVE, HALF_CYCLE, TWO_LEVEL, precondition


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
    known = precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz, t1, t2, work)
    p[:] = z
    if known:  # hp = H p without a pass over K: H z from the preconditioner, H p by the same recurrence as p
        hp[:] = hz
    rz = r @ z
    it = 0
    while it < max_iterations:
        if not (rz > 0.0) and (kind == TWO_LEVEL or kind == HALF_CYCLE):
            # far from rotations E_rot's blocks outgrow 2 (K + σ I) and the multiplicative form can lose
            # definiteness: restart from x with the additive form, which cannot
            kind = ADDITIVE
            known = precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz,
                                  t1, t2, work)
            p[:] = z
            rz = r @ z
        if not known:
            hessian_times(kp, ki, kx, rot, rig, bridges, damp, fac[5], p, hp)
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
            known = precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz,
                                  t1, t2, work)
            p[:] = z
            if known:
                hp[:] = hz
            rz = r @ z
            continue
        fresh = precondition(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, coarse, r, z, hz, t1, t2, work)
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
