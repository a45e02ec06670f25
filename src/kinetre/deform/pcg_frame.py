"""A warm-started PCG frame in one numba call: the start, the jump test and `newton_krylov.gauss_newton_pcg`.

At 2 ms per frame, the Python around the loop was a quarter of it (256 nodes, two skeletons, loaded machine:
~0.6 ms of constraint targets, the start's two energies, the constant-velocity guess, array copies and the
kernel's dispatch). Here the guess 2 x − x_before is made in place and its energy comes with the gradient
the loop starts from (it is the better start on nine frames in ten on the walk), so a frame evaluates E twice
before its first step instead of three times.
"""
from __future__ import annotations

import numpy as np

from ..jit import njit
from .gradient import energy_gradient
from .newton_krylov import gauss_newton_pcg


@njit(cache=True)
def warm_start(x, x0, before, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
               w_rot, w_reg, w_con, w_rig, grad):
    """x (N, 12) ← the frame's start: the last pose x0, or the constant-velocity guess 2 x0 − before when
    its E is lower (`before` of shape (0, 12): no guess). Returns its E; `grad` ← its gradient (12N)."""
    if before.shape[0]:
        for j in range(x.shape[0]):
            for u in range(12):
                x[j, u] = 2.0 * x0[j, u] - before[j, u]
        e_guess = energy_gradient(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                                  w_rot, w_reg, w_con, w_rig, grad, True)
        e0 = energy_gradient(x0, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                             w_rot, w_reg, w_con, w_rig, grad[:0], False)
        if e_guess < e0:
            return e_guess
    x[:] = x0
    return energy_gradient(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                           w_rot, w_reg, w_con, w_rig, grad, True)


@njit(cache=True)
def pcg_frame(x, x0, before, threshold, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
              w_rot, w_reg, w_con, w_rig, kind, fac, kp, ki, kx, k_blocks, k_diag,
              max_iterations, relative_tolerance, cg_iterations, cg_tolerance, lam, max_damping,
              energy_floor, rot, rig, node_fac, energies, backtracks, curvature, coarse, kc,
              contraction, remaining_tolerance, stop, stop_after, grad):
    """`warm_start` into x, then `gauss_newton_pcg` from it, whose 8-tuple it returns; a start whose E
    exceeds `threshold` is a jump (`solver.GaussNewton.solve`): then x holds the start and the tuple is
    (its E, -1, 0, 0, 0, λ, -1, False) without a step taken."""
    energy = warm_start(x, x0, before, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                        w_rot, w_reg, w_con, w_rig, grad)
    if energy > threshold:
        return energy, -1, 0, 0, 0, lam, -1.0, False
    return gauss_newton_pcg(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                            w_rot, w_reg, w_con, w_rig, kind, fac, kp, ki, kx, k_blocks, k_diag,
                            max_iterations, relative_tolerance, cg_iterations, cg_tolerance, lam, max_damping,
                            energy_floor, rot, rig, node_fac, energies, backtracks, curvature, coarse, kc,
                            contraction, remaining_tolerance, stop, stop_after, grad, energy)


@njit(cache=True)
def all_finite(x):
    """Whether every entry of the pose x (N, 12) is finite (`Rig.solve`'s check on each result: numpy's
    isfinite and all, on the caches the frame left cold, cost 40 µs of a 2 ms frame)."""
    for j in range(x.shape[0]):
        for u in range(x.shape[1]):
            if not np.isfinite(x[j, u]):
                return False
    return True
