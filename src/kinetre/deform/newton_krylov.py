"""The damped Gauss-Newton loop of `solver.py` with its steps from `krylov.pcg`, all in one numba call.

Same rules as the exact loop, with two differences measured on the walk (`bench_core`): a step that
does not lower E is first halved (up to `backtracks` times, an energy each) before λ grows and a new
step is solved for; and only a full step whose CG met its tolerance can end the loop by lowering E
by less than `relative_tolerance` of it (a truncated or halved step's small decrease says nothing
about convergence: with one arm possessing, stopping on them ended 10 % above the exact minimum). The
loop also ends after `max_iterations` linear solves or when a Jacobi estimate of the remaining
decrease is negligible. Kept in numba because at 2 ms per frame the Python bookkeeping of a few
iterations would be most of it.
"""
from __future__ import annotations

import numpy as np

from ..jit import njit
from .gradient import energy_gradient
from .coarse_space import coarse_factor
from .krylov import BLOCK_JACOBI, COORDINATE, local_blocks, node_factors, pcg, stretch_curvature
from .live_stop import should_stop


# The coarse space serves only a frame's first two linear solves, each with its factor made afresh. It carries
# the large, slow motions (a whole limb turning) of a frame's first steps. Steps after those mostly creep (a
# pose the targets cannot quite reach: Gauss-Newton converges linearly, ~0.1-1 % of E a step), and there it
# costs a factor and a coarse solve per CG iteration for nothing. A factor made once per frame went stale
# as the pose moved: CG then ran to its cap, and a frame that does not converge in CG cannot stop before its
# last step. bench_network's live solve replayed (two legs on Spot, 253 nodes, 760 frames; thread CPU ms
# per frame, median / p99): factor once a frame, every step 4.4-5.4 / 25.7-29.2 (72 frames out of steps,
# 14.6 CG iterations a frame); refreshed, every step 4.6-5.4 / 24.8-27.7; refreshed, first two steps
# 4.5 / 19.0 (53, 9.7) against 5.6 / 19.6 (60, 14.1) without the coarse space in the same run. One step
# only loses the one-arm agreement (median 1.7e-3 above exact; two: passes). Block Jacobi keeps it on every
# step: nothing else there carries the graph-wide coupling.
COARSE_STEPS = 2


# the least ratio of successive steps' gains the "remaining" stop rule assumes. Without it, one arm possessing a
# 256-node body: its frames' second steps gain 1e-3 of the first, the carried ratio fell to 0, and frames ended
# after one step 5-11 % above the exact solve; d₃/d₂ there is 0.05-0.5
RATIO_FLOOR = 0.1


@njit(cache=True)
def gauss_newton_pcg(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                     w_rot, w_reg, w_con, w_rig, kind, fac, kp, ki, kx, k_blocks, k_diag,
                     max_iterations, relative_tolerance, cg_iterations, cg_tolerance, lam, max_damping,
                     energy_floor, rot, rig, node_fac, energies, backtracks, curvature, coarse, kc,
                     contraction, remaining_tolerance, stop, stop_after, grad, start_energy):
    """Minimise E from x (N, 12, updated in place), whose E is `start_energy` and gradient `grad` (12N) when
    the caller has them (`pcg_frame.warm_start`; NaN: computed here into `grad`). Returns (E, iterations,
    accepted, CG iterations,
    number of entries written to `energies` (E after each accepted step, from the initial E), λ, the last
    ratio of two successive accepted steps' decreases seen in this frame (-1: none), whether `stop` ended it).
    `stop` (uint8, shape (1,), or (0,): none) and `stop_after`: a live solve's `live_stop.Yield`; the frame
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
            if kind != COORDINATE:
                node_factors(k_blocks, rot, rig, bridges, damp, node_fac)
            # λ below 1e-2 barely changes H's diagonal (λ diag(H) is added to it): not worth a refactor
            use = coarse if iterations <= COARSE_STEPS or kind == BLOCK_JACOBI else no_coarse
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
                    # CG iterates from 0): the damping stays higher, fewer steps overshoot than with
                    # the true ratio (5.5 against 4.1 solves per frame on the walk)
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
