"""The fast path's frame: the damped Gauss-Newton loop of `solver.py` with its steps from truncated PCG
(`cg.py`), start and jump test included, all in one numba call (at a few ms per frame the Python bookkeeping
around a few iterations would be a large part of it).

Same rules as the exact loop, with two differences: a step that does not lower E is first halved (up to
`backtracks` times, an energy each) before λ grows and a new step is solved for; and only a full step whose
CG met its tolerance can end the loop by lowering E by less than `relative_tolerance` of it (a truncated or
halved step's small decrease says nothing about convergence). Such a step also ends it when the next step
would gain less than `remaining_tolerance` of E (the "remaining" rule, below). The loop also ends after
`max_iterations` linear solves or when a Jacobi estimate of the remaining decrease is negligible.
"""
from __future__ import annotations

import numpy as np

from ...jit import njit
from .cg import pcg
from .coarse_space import coarse_factor
from .energy import energy_gradient
from .hessian import local_blocks, stretch_curvature
from .live_stop import should_stop
from .preconditioner import node_factors

# The coarse space serves only a frame's first two linear solves, each with its factor made afresh: it carries
# the large, slow motions (a whole limb turning) of a frame's first steps. The steps after those mostly creep
# (Gauss-Newton converging linearly on a pose the targets cannot quite reach), where it would cost a factor and
# a coarse solve per CG iteration for nothing; a factor kept for the whole frame goes stale as the pose moves,
# and CG then runs to its cap. With one solve only, frames end measurably above the exact minimum when one arm
# possesses a body.
COARSE_STEPS = 2

# the least ratio of successive steps' gains the "remaining" rule assumes: a frame's first step (the tracked
# motion) can gain far more than the slow modes after it, and a ratio carried over from such frames would end
# the next ones after one step, well above the minimum
RATIO_FLOOR = 0.1


# numpy's error model: Python's tests every division for zero, which keeps the loops over the unknowns from being
# vectorised; every denominator here is positive
@njit(cache=True, error_model="numpy")
def gauss_newton_pcg(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                     w_rot, w_reg, w_con, w_rig, kind, fac, kp, ki, kx, k_blocks, k_diag,
                     max_iterations, relative_tolerance, cg_iterations, cg_tolerance, lam, max_damping,
                     energy_floor, rot, rig, node_fac, energies, backtracks, curvature, coarse, kc,
                     contraction, remaining_tolerance, stop, stop_after, grad, start_energy):
    """Minimise E from x (N, 12, updated in place), whose E is `start_energy` and gradient `grad` (12N) when
    the caller has them (`warm_start`; NaN: computed here into `grad`). Returns (E, iterations,
    accepted, CG iterations,
    number of entries written to `energies` (E after each accepted step, from the initial E), λ, the last
    ratio of two successive accepted steps' decreases seen in this frame (-1: none), whether `stop` ended it).
    `stop` (uint8, shape (1,), or (0,): none) and `stop_after`: a live solve's `Yield` (`live_stop.py`); the frame
    ends after an accepted step, not converged, once stop[0] is set and the thread's CPU clock is past
    `stop_after` (E lowered; the next frame goes on from this pose).
    `coarse` = (factor (12m, 12m), region, offsets) and kc: the coarse space of `coarse_space.py` (a factor of
    shape (0, 0): none). It serves the frame's first `COARSE_STEPS` linear solves only, factored afresh for
    each step (the pose moved: its node blocks changed) and for a retry only when λ + 0.01 has moved 4×;
    see `COARSE_STEPS` for why."""
    n = x.shape[0]
    m = 12 * n
    neg = np.empty(m)
    diag = np.empty(m)
    damp = np.empty(m)
    x_new = np.empty_like(x)
    R = np.empty((n, 3, 3))
    energy = start_energy
    if not start_energy >= 0.0:
        energy = energy_gradient(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                                 w_rot, w_reg, w_con, w_rig, grad, True)
    energies[0] = energy
    count = 1
    nu = 2.0
    iterations = accepted = cg_total = 0
    decrease = 0.0
    previous = -1.0  # the decrease of the accepted step before
    ratio_seen = -1.0
    trial = np.empty(m)
    no_coarse = (np.zeros((0, 0)), coarse[1], coarse[2])
    stopped = False
    while iterations < max_iterations and energy > energy_floor:
        coarse_lam = -1.0  # the damping the coarse factor was made with; -1: none (a new pose: refactor)
        for j in range(n):
            for a in range(3):
                for b in range(3):
                    R[j, a, b] = x[j, 3 * a + b]
        local_blocks(R, bridges, w_rot, w_rig, rot, rig)
        if curvature:
            stretch_curvature(R, w_rot, rot)
        # diag(JᵀJ) for the damping, floored so a node the terms barely see still gets some
        top = 0.0
        for i in range(m):
            diag[i] = k_diag[i // 3]
        for j in range(n):
            for u in range(9):
                diag[12 * j + u] += rot[j, u, u]
        for e in range(bridges.shape[0]):
            for u in range(9):
                diag[12 * bridges[e, 0] + u] += rig[e, u, u]
                diag[12 * bridges[e, 1] + u] += rig[e, 9 + u, 9 + u]
        for i in range(m):
            top = max(top, diag[i])
        floor = 1e-9 * max(top, 1e-300)
        estimate = 0.0
        for i in range(m):
            diag[i] = max(diag[i], floor)
            estimate += grad[i] * grad[i] / diag[i]
        # a Jacobi estimate of what a full step could still gain: negligible → converged
        if estimate <= 1e-2 * relative_tolerance * energy:
            break
        for i in range(m):
            neg[i] = -grad[i]
        stepped = False
        while iterations < max_iterations:
            iterations += 1
            for i in range(m):
                damp[i] = lam * diag[i]
            node_factors(k_blocks, rot, rig, bridges, damp, node_fac)
            # λ below 1e-2 barely changes H's diagonal (λ diag(H) is added to it): not worth a refactor
            use = coarse if iterations <= COARSE_STEPS else no_coarse
            if use[0].shape[0] and not (0.25 * (coarse_lam + 1e-2) <= lam + 1e-2 <= 4.0 * (coarse_lam + 1e-2)):
                coarse_factor(kc, coarse[1], coarse[2], rot, rig, bridges, damp, coarse[0])
                coarse_lam = lam
            dy, it, converged = pcg(kind, fac, kp, ki, kx, rot, rig, bridges, damp, node_fac, use, neg,
                                    cg_iterations, cg_tolerance)
            cg_total += it
            predicted = neg @ dy  # the model's decrease, up to the damping term
            if not predicted > 1e-3 * relative_tolerance * energy:
                break
            for j in range(n):
                o = 12 * j
                for a in range(3):
                    for b in range(3):
                        x_new[j, 3 * a + b] = x[j, 3 * a + b] + dy[o + 3 * b + a]
                    x_new[j, 9 + a] = x[j, 9 + a] + dy[o + 9 + a]
            # the gradient comes almost free with the energy, and is the next one if the step is taken
            e_new = energy_gradient(x_new, g, edges, con_nodes, con_weights, con_points, targets, active,
                                    bridges, w_rot, w_reg, w_con, w_rig, trial, True)
            if not (np.isfinite(e_new) and e_new < energy):
                # the model overshot: the same direction shortened costs an energy, a new one a solve
                for _ in range(backtracks):
                    for j in range(n):
                        for u in range(12):
                            x_new[j, u] = 0.5 * (x_new[j, u] + x[j, u])
                    predicted *= 0.5
                    e_new = energy_gradient(x_new, g, edges, con_nodes, con_weights, con_points, targets,
                                            active, bridges, w_rot, w_reg, w_con, w_rig, trial, True)
                    if np.isfinite(e_new) and e_new < energy:
                        break
                if np.isfinite(e_new) and e_new < energy:
                    lam = max(lam, 1e-6) * nu  # a poor model: damp the next steps more
                    nu *= 2.0
                    predicted = -1.0  # no gain-ratio update below, and no convergence test on this step
            if np.isfinite(e_new) and e_new < energy:
                decrease = energy - e_new
                if predicted > 0.0:
                    # Nielsen's update from the gain ratio, against bᵀx (twice the model's decrease for
                    # CG iterates from 0): the damping stays higher, so fewer steps overshoot and a frame
                    # needs fewer solves than with the true ratio
                    rho = decrease / max(predicted, 1e-300)
                    lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-12)
                    nu = 2.0
                x[:] = x_new
                grad[:] = trial
                energy = e_new
                energies[count] = energy
                count += 1
                accepted += 1
                stepped = True
                break
            lam = max(lam, 1e-6) * nu
            nu *= 2.0
            if lam > max_damping:
                break
        if not stepped:
            break
        ratio = contraction
        if previous > 0.0:
            ratio = min(decrease / previous, 1.0)
            ratio_seen = ratio
        previous = decrease
        if converged and predicted > 0.0:
            if decrease <= relative_tolerance * energies[count - 2]:
                break
            # the next step would gain about `ratio` of this one (linear convergence): stop when that is
            # negligible, instead of taking it only to see that it was. A frame's first step (the tracked
            # motion) can gain far more than the slow modes after it, so the ratio is floored. Never stricter
            # than the rule above: on creeping frames (ratio 0.5-1) it would ask for more steps
            if remaining_tolerance > 0.0 and max(ratio, RATIO_FLOOR) * decrease <= remaining_tolerance * energy:
                break
        if iterations < max_iterations and should_stop(stop, stop_after):
            stopped = True
            break
    return energy, iterations, accepted, cg_total, count, lam, ratio_seen, stopped


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
    exceeds `threshold` is a jump (`GaussNewton.solve` in `solver.py`): then x holds the start and the tuple is
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
    isfinite and all, on the caches the frame left cold, cost a visible share of a frame)."""
    for j in range(x.shape[0]):
        for u in range(x.shape[1]):
            if not np.isfinite(x[j, u]):
                return False
    return True
