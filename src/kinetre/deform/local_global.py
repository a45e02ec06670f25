"""A local/global alternative to the Gauss-Newton loop, accelerated by Anderson mixing (issue 9).

E (Eq. 8) = Q(y) + F(R): Q, the linear terms E_reg, E_con and E_rig's gap, is quadratic with the
Hessian K ⊗ I₃ that is fixed per rig (`coordinate_split.py`); F, E_rot (Eq. 3) and E_rig's R_kᵀR_j − I,
couples unknowns only within a node (and across a bridge). One iteration is the map G(y):

- global: y' = y − α S ∇E(y), S = (K_σ ⊗ I₃)⁻¹ with the rig's factor (one pair of triangular solves on
  the 4N system for x, y and z at once): the exact minimiser of Q plus F's model f + ∇f·δ + σ/2 |δ_R|²,
  whose curvature σ = 2 w_rot (+ w_rig per bridge) is E_rot's averaged over rotations. Where E_rot is
  stiffer (a stretch) the full step overshoots: α is the secant zero of E's slope along the step, the
  slope at its end from ∇E(y') = (g − ∇F(y)) − α (g − σ S g) + ∇F(y'), node-local work only;
- local: y'' = y' − ω B(y')⁻¹ ∇E(y'), a Newton step per node on its own 12 unknowns with every other
  node fixed: B is the node's block of Gauss-Newton's JᵀJ (K's 4×4 block per coordinate plus E_rot's,
  E_rig's 9×9), which carries the rotation stiffness that σ only averages; ω < 1 since all nodes move
  at once (block Jacobi).

Both steps vanish exactly where ∇E = 0, so G's fixed points are the true stationary points of E, not
those of an ARAP-like surrogate. Anderson mixing (type II, the last `memory` iterates) accelerates the
fixed-point iteration. E never increases: the mixed iterate is kept only when it lowers E, else G(y) if
that does, else y' alone; when none does, the caller hands the frame to Gauss-Newton (`solver.py`).
The loop stops when the global step's predicted gain g·S g falls below a fraction of E — which misses
slow, graph-wide rotation modes (one arm possessing a body creeps for tens of iterations), hence the
default hand-over to Gauss-Newton after `then_gauss_newton` (one) iteration: the local/global step as
the initial guess of the PCG loop.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..jit import njit
from .gradient import energy_gradient
from .krylov import _coordinate_solve, _node_solve, local_blocks, node_factors
from .normal_equations import _ROT_P, _ROT_Q

CONVERGED, STALLED, OUT_OF_ITERATIONS = 0, 1, 2


@dataclass(frozen=True)
class LocalGlobalSettings:
    """Settings of `SolverSettings(method="local_global")`.

    memory : Anderson history length (0: plain fixed-point iteration)
    local : with the per-node Newton step after the global one (False: the global step alone)
    max_iterations : local/global iterations per frame at most
    then_gauss_newton : hand over to Gauss-Newton/PCG after this many iterations unless converged (0:
        only when no candidate lowers E, or after `max_iterations`)
    gain_tolerance : stop when g·S g ≤ gain_tolerance · E
    line_search : shorten the global step where E's slope along it turns (from the energy and gradient
        evaluated at its end anyway)
    relaxation : the local step's length (1: the node Newton step; shorter, since all nodes move at once)
    refactor : refactor the node blocks B at every iteration (else once per frame, at the first one)
    """

    memory: int = 3
    local: bool = True
    max_iterations: int = 20
    then_gauss_newton: int = 1
    gain_tolerance: float = 1e-5
    line_search: bool = True
    relaxation: float = 0.7
    refactor: bool = True

    def __post_init__(self):
        if self.memory < 0 or self.max_iterations < 1 or self.then_gauss_newton < 0 or not self.gain_tolerance > 0:
            raise ValueError(f"invalid LocalGlobalSettings {self!r}")


@njit(cache=True)
def _layout(x, y, to_coordinate):
    """y (12N, the coordinate layout of `krylov.py`) ← x (N, 12, solver layout), or back."""
    for j in range(x.shape[0]):
        o = 12 * j
        for u in range(12):
            v = u if u >= 9 else 3 * (u % 3) + u // 3  # R[a, b] at 3 a + b in x, 3 b + a in y
            if to_coordinate:
                y[o + v] = x[j, u]
            else:
                x[j, u] = y[o + v]


@njit(cache=True)
def _nonlinear_gradient(y, bridges, w_rot, w_rig, out):
    """out = ∇F/2 at y (coordinate layout): E_rot's (Eq. 3) and E_rig's R_kᵀR_j − I (Eq. 7) terms of
    `gradient.energy_gradient`, whose columns c_b of R_j are contiguous here (y[12 j + 3 b : + 3])."""
    out[:] = 0.0
    for j in range(y.shape[0] // 12):
        for r in range(6):
            _column_pair(y, 12 * j + 3 * _ROT_P[r], 12 * j + 3 * _ROT_Q[r], _ROT_P[r] == _ROT_Q[r], w_rot, out)
    for e in range(bridges.shape[0]):
        for a in range(3):
            for b in range(3):  # (R_kᵀ R_j)[a, b] = column a of R_k · column b of R_j
                _column_pair(y, 12 * bridges[e, 1] + 3 * a, 12 * bridges[e, 0] + 3 * b, a == b, w_rig, out)


@njit(cache=True)
def _column_pair(y, oa, ob, diagonal, w, out):
    """The residual r = c·c' − [diagonal] of columns c = y[oa : oa + 3], c' = y[ob : ob + 3]: out += w r ∂r."""
    r = y[oa] * y[ob] + y[oa + 1] * y[ob + 1] + y[oa + 2] * y[ob + 2]
    if diagonal:
        r -= 1.0
    r *= w
    for c in range(3):
        out[oa + c] += r * y[ob + c]
        out[ob + c] += r * y[oa + c]


@njit(cache=True)
def _anderson(y, f, dys, dfs, count, memory, out):
    """out = y + f − Σ γ_i (Δy_i + Δf_i), γ = argmin |f − Σ γ_i Δf_i| over the `count` stored differences
    (rows of dys, dfs, a ring of `memory`). Returns False when the least-squares problem is degenerate."""
    h = min(count, memory)
    a = np.empty((h, h))
    rhs = np.empty(h)
    for i in range(h):
        rhs[i] = dfs[i] @ f
        for k in range(i, h):
            s = dfs[i] @ dfs[k]
            a[i, k] = s
            a[k, i] = s
    scale = 0.0
    for i in range(h):
        scale = max(scale, a[i, i])
    if not scale > 0.0:
        return False
    for i in range(h):
        a[i, i] += 1e-10 * scale  # Tikhonov: nearly parallel differences stay solvable
    gamma = np.linalg.solve(a, rhs)
    for p in range(y.shape[0]):
        out[p] = y[p] + f[p]
    for i in range(h):
        gi = gamma[i]
        if not np.isfinite(gi):
            return False
        for p in range(y.shape[0]):
            out[p] -= gi * (dys[i, p] + dfs[i, p])
    return True


@njit(cache=True)
def local_global(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                 w_rot, w_reg, w_con, w_rig, fac, k_blocks, k_diag, memory, local, line_search, relaxation,
                 refactor, max_iterations, gain_tolerance, energy_floor, rot, rig, node_fac, energies):
    """Minimise E from x (N, 12, updated in place) by Anderson-accelerated local/global iterations.

    Returns (E, iterations, accepted, entries written to `energies`, status): CONVERGED, STALLED (no
    candidate lowered E: x is the last accepted iterate) or OUT_OF_ITERATIONS.
    """
    n = x.shape[0]
    m = 12 * n
    grad = np.empty(m)
    g1 = np.empty(m)
    trial_grad = np.empty(m)
    y = np.empty(m)
    y1 = np.empty(m)
    gy = np.empty(m)
    gf = np.empty(m)
    f = np.empty(m)
    f_prev = np.empty(m)
    y_prev = np.empty(m)
    cand = np.empty(m)
    s = np.empty(m)
    work = np.empty(m)
    damp = np.empty(m)
    xt = np.empty_like(x)
    R = np.empty((n, 3, 3))
    dys = np.zeros((max(memory, 1), m))
    dfs = np.zeros((max(memory, 1), m))
    shift = fac[5]
    top = 0.0
    for i in range(m):
        top = max(top, k_diag[i // 3])
    for i in range(m):
        damp[i] = 1e-6 * max(k_diag[i // 3], 1e-3 * top)  # keeps a node block definite far from rotations
    _layout(x, y, True)
    energy = energy_gradient(x, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                             w_rot, w_reg, w_con, w_rig, grad, True)
    energies[0] = energy
    count = 1
    stored = 0
    have_prev = False
    iterations = accepted = 0
    status = OUT_OF_ITERATIONS
    factored = False
    while iterations < max_iterations:
        if energy <= energy_floor:
            status = CONVERGED
            break
        _coordinate_solve(fac, grad, s, work)
        gain = grad @ s
        if not gain > gain_tolerance * energy:
            status = CONVERGED
            break
        iterations += 1
        for p in range(m):
            y1[p] = y[p] - s[p]
        # ∇E at y − α s without a pass over the terms: since (K_σ ⊗ I₃) s = g, the quadratic part's
        # gradient is (g − ∇F(y)) − α (g − σ s); only F's node-local gradient is evaluated again
        _nonlinear_gradient(y, bridges, w_rot, w_rig, gf)
        _nonlinear_gradient(y1, bridges, w_rot, w_rig, g1)
        for p in range(m):
            g1[p] += shift[p] * s[p] - gf[p]
        alpha = 1.0
        slope = -(g1 @ s)  # E's slope along the step at its end (−g·s at its start)
        if line_search and slope > 0.0:
            # E_rot stiffer than σ on a stretch: the step overshoots; take the secant zero of the slope
            alpha = max(gain / (gain + slope), 0.1)
            for p in range(m):
                y1[p] = y[p] - alpha * s[p]
            _nonlinear_gradient(y1, bridges, w_rot, w_rig, g1)
            for p in range(m):
                g1[p] += grad[p] - gf[p] - alpha * (grad[p] - shift[p] * s[p])
        if local:
            if refactor or not factored:
                _layout(xt, y1, False)
                for j in range(n):
                    for a in range(3):
                        for b in range(3):
                            R[j, a, b] = xt[j, 3 * a + b]
                local_blocks(R, bridges, w_rot, w_rig, rot, rig)
                node_factors(k_blocks, rot, rig, bridges, damp, node_fac)
                factored = True
            _node_solve(node_fac, g1, s)
            for p in range(m):
                gy[p] = y1[p] - relaxation * s[p]
        else:
            gy[:] = y1
        for p in range(m):
            f[p] = gy[p] - y[p]
        mixed = False
        if memory > 0 and have_prev:
            slot = stored % memory
            for p in range(m):
                dys[slot, p] = y[p] - y_prev[p]
                dfs[slot, p] = f[p] - f_prev[p]
            stored += 1
            mixed = _anderson(y, f, dys, dfs, stored, memory, cand)
        if not mixed:
            cand[:] = gy
        # candidates in order: the mixed iterate, G(y), the global step alone
        e_new = np.inf
        for which in range(3):
            if which == 1 and not mixed:
                continue
            if which == 1:
                cand[:] = gy
                stored = 0  # the mixing overshot: start its history again
            if which == 2:
                if not local:
                    break
                cand[:] = y1
                stored = 0
            _layout(xt, cand, False)
            e_new = energy_gradient(xt, g, edges, con_nodes, con_weights, con_points, targets, active, bridges,
                                    w_rot, w_reg, w_con, w_rig, trial_grad, True)
            if np.isfinite(e_new) and e_new < energy:
                break
        if not (np.isfinite(e_new) and e_new < energy):
            status = STALLED
            break
        y_prev[:] = y
        f_prev[:] = f
        have_prev = True
        y[:] = cand
        x[:] = xt
        grad[:] = trial_grad
        energy = e_new
        energies[count] = energy
        count += 1
        accepted += 1
    return energy, iterations, accepted, count, status


def solve_frame(system, split_data, settings: LocalGlobalSettings, x0: np.ndarray, targets: np.ndarray,
                active: np.ndarray, energy_floor: float, rot: np.ndarray, rig: np.ndarray, node_fac: np.ndarray):
    """`local_global` for a rig's `NormalEquations` and the data of `CoordinateSplit.frame_data`; rot, rig,
    node_fac: scratch blocks. Returns (x, E, iterations, accepted steps, energies, converged), the iterations
    limited to `then_gauss_newton` when it is set."""
    _, fac, k_blocks, _, k_diag = split_data
    w, cons = system.weights, system.constraints
    x = np.array(x0, dtype=np.float64, order="C")
    energies = np.empty(settings.max_iterations + 1)
    energy, iterations, accepted, count, status = local_global(
        x, system.g, system.edges, cons.nodes, cons.weights, cons.points,
        np.ascontiguousarray(targets, dtype=np.float64), np.ascontiguousarray(active, dtype=np.float64),
        system.bridges, w.rot, w.reg, w.con, w.rig, fac, k_blocks, k_diag, settings.memory, settings.local,
        settings.line_search, settings.relaxation, settings.refactor,
        settings.then_gauss_newton or settings.max_iterations, settings.gain_tolerance, energy_floor, rot, rig,
        node_fac, energies)
    return x, energy, iterations, accepted, tuple(energies[:count]), status == CONVERGED
