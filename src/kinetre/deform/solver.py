"""Gauss-Newton with Levenberg-Marquardt damping on the Eq. 8 energy, warm-started per frame.

Each iteration solves (JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr with the factorisation's symbolic analysis reused.
A step that does not lower E is rejected and λ grows, so E never increases. The loop stops after
`max_iterations` steps, or as soon as an accepted step's decrease is negligible — checked before
factoring again, so no factorisation is spent only to confirm convergence.

With `reuse_factor` the numeric factor of an earlier iteration (or frame) is kept while its steps
keep lowering E, and refreshed when one does not: an inexact Newton step that trades a few more,
much cheaper iterations for far fewer factorisations (ours; see the benchmark).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .factor import NotPositiveDefinite, ReusedCholesky
from .normal_equations import NormalEquations


@dataclass(frozen=True)
class SolverSettings:
    max_iterations: int = 10
    relative_tolerance: float = 1e-3   # stop when an accepted step lowers E by less than this fraction
    initial_damping: float = 1e-6
    max_damping: float = 1e8
    reuse_factor: bool = False


@dataclass(frozen=True)
class SolveReport:
    x: np.ndarray          # (N, 12)
    energy: float
    iterations: int        # linear solves (steps tried)
    accepted: int          # accepted steps
    factorisations: int    # numeric factorisations done
    energies: tuple        # E after each accepted step, starting with the initial E


class GaussNewton:
    """Solver state for one rig: the normal-equation pattern and its reused symbolic factor."""

    def __init__(self, system: NormalEquations, settings: SolverSettings = SolverSettings(),
                 backend: str | None = None):
        self.system = system
        self.settings = settings
        self.factor = ReusedCholesky(system.matrix(np.ones(len(system.indices))), backend)
        # Below this, residuals are at round-off level (1e-10 of the graph's size per residual).
        extent = float(np.ptp(system.b_con.reshape(-1, 3), axis=0).max()) if len(system.b_con) else 1.0
        rows = 6 * system.n // 12 + len(system.b_reg) + len(system.b_con)
        self.energy_floor = (1e-10 * max(extent, 1e-300)) ** 2 * rows * max(system.weights.con, 1.0)
        self._active_key = None
        self._linear_data = None
        self._factored = False
        self._diag = None
        self._lam = None

    def _linear(self, active: np.ndarray) -> np.ndarray:
        key = active.tobytes()
        if key != self._active_key:
            self._linear_data = self.system.const_data + self.system.constraint_data(active)
            self._active_key = key
            self._factored = False
        return self._linear_data

    def solve(self, x0: np.ndarray, targets: np.ndarray, active: np.ndarray) -> SolveReport:
        s = self.settings
        sysm = self.system
        linear = self._linear(active)
        x = x0.copy()
        parts = sysm.residuals(x, targets, active)
        energy = sysm.energy(parts)
        energies = [energy]
        # damping carries over from the previous frame: its scale is a property of the rig
        lam = self._lam if self._lam is not None else s.initial_damping
        nu = 2.0
        iterations = factorisations = accepted = 0
        reusable = s.reuse_factor and self._factored
        while iterations < s.max_iterations and energy > self.energy_floor:
            data, grad = sysm.system(x, parts, None if reusable else linear, active)
            if data is not None:
                self._diag = data[sysm.diag_pos]
            diag = self._diag
            floor = 1e-9 * max(diag.max(), 1e-300)
            # A Jacobi estimate of what a full step could still gain: when it is negligible the
            # pose is converged and no factorisation is spent confirming it.
            if grad @ (grad / np.maximum(diag, floor)) <= 1e-2 * s.relative_tolerance * energy:
                break
            stepped = False
            while iterations < s.max_iterations:
                iterations += 1
                reused = reusable
                try:
                    if reused:
                        delta = self.factor.solve(None, -grad)
                    else:
                        if data is None:
                            data, _ = sysm.system(x, parts, linear, active)
                            diag = self._diag = data[sysm.diag_pos]
                            floor = 1e-9 * max(diag.max(), 1e-300)
                        damped = data.copy()
                        damped[sysm.diag_pos] += lam * np.maximum(diag, floor)
                        factorisations += 1
                        self._factored = False
                        delta = self.factor.solve(sysm.matrix(damped), -grad)
                        self._factored = True
                except NotPositiveDefinite:
                    lam = min(max(lam * 10.0, 1e-6), s.max_damping)
                    continue
                predicted = -(grad @ delta)  # the GN model's decrease, up to the damping term
                if predicted <= 1e-3 * s.relative_tolerance * energy:
                    if reused:
                        reusable = False  # a stale factor may just point the wrong way
                        continue
                    break
                x_new = x + delta.reshape(x.shape)
                parts_new = sysm.residuals(x_new, targets, active)
                e_new = sysm.energy(parts_new)
                if np.isfinite(e_new) and e_new < energy:
                    decrease = energy - e_new
                    if not reused:
                        # Nielsen's update from the gain ratio: a step the model predicted well
                        # lowers the damping, a poor one keeps it
                        rho = decrease / max(predicted, 1e-300)
                        lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-12)
                        nu = 2.0
                    x, parts, energy = x_new, parts_new, e_new
                    energies.append(energy)
                    accepted += 1
                    reusable = s.reuse_factor
                    stepped = True
                    break
                if reused:
                    reusable = False  # refresh the factor before raising the damping
                    continue
                lam *= nu
                nu *= 2.0
                if lam > s.max_damping:
                    break
            if not stepped or decrease <= s.relative_tolerance * energies[-2]:
                break
        self._lam = min(max(lam, s.initial_damping), 1e3)
        return SolveReport(x=x, energy=energy, iterations=iterations, accepted=accepted,
                           energies=tuple(energies), factorisations=factorisations)
