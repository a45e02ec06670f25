"""The solver: its settings, the damped Gauss-Newton loop on E (Eq. 8) and the exact reference solve.

Per frame, warm-started from the last pose, Gauss-Newton with Levenberg-Marquardt damping: each step solves
(JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr and is kept only when it lowers E, else λ grows, so E never increases.
- `method="exact"` (the reference, also every rig's first frame): δ from a sparse Cholesky of the full 12N
  system (`normal_equations.py`, `factor.py`), its symbolic analysis reused; the loop is `_solve_exact`.
- `method="pcg"` (default): the same loop with δ from a few conjugate-gradient iterations, preconditioned by
  a per-coordinate factor of the linear terms and per-node blocks, in one numba call per frame (`fast/`).
A frame whose start is far above the last result (a skeleton teleporting) is a jump: it starts from the best
rigid motion of the pose onto the targets when that fits better (`rigid_start.py`) and gets twice the steps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import BadSettingsError
from .factor import NotPositiveDefinite, ReusedCholesky
from .fast.coordinate_split import CoordinateSplit
from .fast.energy import energy_gradient
from .fast.gauss_newton import pcg_frame
from .fast.live_stop import NO_FLAG, Yield
from .fast.preconditioner import HALF_CYCLE, TWO_LEVEL, node_factor_buffer
from .normal_equations import NormalEquations
from .rigid_start import rigid_start

# the preconditioners whose frames end by the "remaining" rule (with the coarse space, by the decrease alone)
REMAINING_TIERS = (HALF_CYCLE, TWO_LEVEL)

# "half_cycle" and "two_level" fix one of the adaptive choice's two tiers (tests and benchmarks take them apart)
PRECONDITIONERS = {"two_level": TWO_LEVEL, "half_cycle": HALF_CYCLE, "adaptive": HALF_CYCLE}


@dataclass(frozen=True)
class SolverSettings:
    """How `Rig.solve` minimises E per frame.

    max_iterations : linear solves (steps tried) per frame at most; a jump frame gets twice as many
    relative_tolerance : a frame ends when an accepted step lowers E by less than this fraction of it
    initial_damping, max_damping : λ of the first step, and the λ at which a frame gives up on its step
    method : "pcg" (default: the fast path, `fast/`) or "exact" (sparse Cholesky of the full system, the
        reference)
    preconditioner : for "pcg": "adaptive" (default) follows the CG iterations per step of the last frames:
        the half cycle while steps need about one, else the two-level, with the coarse space joining in when
        they need many (`GaussNewton._preconditioner`); "half_cycle" or "two_level" fix one
        (`fast/preconditioner.py`)
    cg_iterations, cg_tolerance : CG iterations per Gauss-Newton step at most, and the relative residual that
        ends them earlier
    jump : a frame whose starting E exceeds `jump` times the last solve's result is a jump: it starts from the
        best rigid motion of the pose onto the targets when that fits better (`rigid_start.py`), and if it is
        still a jump it gets twice the steps, of `jump_steps`
    jump_steps : "pcg" (default) or "exact"; exact steps can be cut short by `Rig.solve`'s `stop` and go on
        over the next frames. "exact" is the oracle the tests hold the PCG jump steps to
    backtracks : for "pcg": halvings of a step that raised E tried before solving for a new one
    curvature : for "pcg": add E_rot's own curvature on stretched columns to the Gauss-Newton blocks
        (`fast/hessian.stretch_curvature`): a Newton step where Gauss-Newton's would overshoot
    coarse_regions : for "pcg": a coarse space of this many regions' affine motions in the preconditioner
        (`fast/coarse_space.py`), for whole limbs turning; 0: none
    remaining_tolerance : for "pcg" on the half cycle's and the two-level's frames: a frame also ends after a
        full step whose CG met its tolerance when the next step would gain less than this fraction of E,
        estimated from this step's gain and the ratio of the last two (linear convergence); 0: only
        `relative_tolerance` ends it
    """

    max_iterations: int = 10
    relative_tolerance: float = 1e-3
    initial_damping: float = 1e-6
    max_damping: float = 1e8
    method: str = "pcg"
    preconditioner: str = "adaptive"
    cg_iterations: int = 8
    cg_tolerance: float = 0.2
    jump: float = 10.0
    jump_steps: str = "pcg"
    backtracks: int = 2
    curvature: bool = True
    coarse_regions: int = 8
    remaining_tolerance: float = 3e-4

    def __post_init__(self):
        if self.method not in ("pcg", "exact"):
            raise BadSettingsError(f"SolverSettings.method must be 'pcg' or 'exact', got {self.method!r}")
        if self.jump_steps not in ("pcg", "exact"):
            raise BadSettingsError(f"SolverSettings.jump_steps must be 'pcg' or 'exact', got {self.jump_steps!r}")
        if self.preconditioner not in PRECONDITIONERS:
            raise BadSettingsError(f"SolverSettings.preconditioner must be one of {sorted(PRECONDITIONERS)}, "
                                   f"got {self.preconditioner!r}")
        counts = {"max_iterations": (self.max_iterations, 1), "cg_iterations": (self.cg_iterations, 1),
                  "backtracks": (self.backtracks, 0), "coarse_regions": (self.coarse_regions, 0)}
        for name, (value, least) in counts.items():
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < least:
                raise BadSettingsError(f"SolverSettings.{name} must be an integer of at least {least}, got {value!r}")
        amounts = {"relative_tolerance": self.relative_tolerance, "remaining_tolerance": self.remaining_tolerance,
                   "cg_tolerance": self.cg_tolerance, "initial_damping": self.initial_damping,
                   "max_damping": self.max_damping, "jump": self.jump}
        for name, value in amounts.items():
            if not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(value) or value < 0:
                raise BadSettingsError(f"SolverSettings.{name} must be a finite number of at least 0, got {value!r}")
        if not 0 < self.initial_damping <= self.max_damping:
            raise BadSettingsError(f"SolverSettings needs 0 < initial_damping <= max_damping, got "
                                   f"{self.initial_damping!r} and {self.max_damping!r}")


@dataclass(frozen=True)
class SolveReport:
    x: np.ndarray          # (N, 12)
    energy: float
    iterations: int        # linear solves (steps tried)
    accepted: int          # accepted steps
    factorisations: int    # numeric factorisations done (of K_σ for "pcg", of JᵀJ for "exact")
    energies: tuple        # E after each accepted step, starting with the initial E
    cg_iterations: int = 0  # conjugate-gradient iterations ("pcg")
    stopped: bool = False   # ended early by `stop` (a newer frame waits), not converged


class GaussNewton:
    """Solver state for one rig: the per-coordinate factor ("pcg") or the full pattern's symbolic
    factor ("exact")."""

    def __init__(self, system: NormalEquations, settings: SolverSettings = SolverSettings(),
                 backend: str | None = None):
        self.system = system
        self.settings = settings
        self._backend = backend
        self._factor = None
        self.split = CoordinateSplit(system, backend, settings.coarse_regions) if settings.method != "exact" else None
        nodes = system.n // 12
        self._rot = np.zeros((nodes, 9, 9))
        self._rig = np.zeros((len(system.bridges), 18, 18))
        self._node_fac = node_factor_buffer(nodes)
        count = 0 if self.split is None or not settings.coarse_regions else int(self.split.region.max()) + 1
        region = self.split.region if self.split is not None else np.zeros(nodes, np.int64)
        offsets = self.split.offsets if self.split is not None else np.zeros((nodes, 3))
        self._coarse = (np.zeros((12 * count, 12 * count)), region, offsets)
        self._no_coarse = (np.zeros((0, 0)), region, offsets)
        self._coarse_on = False  # "adaptive": the coarse space is in use
        self._no_gradient = np.zeros(0)
        # the PCG frame's buffers: the gradient, E after each step (a jump's doubled budget included), and
        # "no pose before" (no constant-velocity guess)
        self._grad = np.zeros(system.n)
        self._energies = np.zeros(2 * settings.max_iterations + 1)
        self._no_pose = np.zeros((0, 12))
        self._last_energy = None  # the last solve's result ("pcg")
        self._jump_left = 0  # exact steps left to a jump that `stop` cut short (it goes on next frame)
        # Below this, residuals are at round-off level (1e-10 of the graph's size per residual).
        extent = float(np.ptp(system.b_con.reshape(-1, 3), axis=0).max()) if len(system.b_con) else 1.0
        rows = 6 * system.n // 12 + len(system.b_reg) + len(system.b_con)
        self.energy_floor = (1e-10 * max(extent, 1e-300)) ** 2 * rows * max(system.weights.con, 1.0)
        self._active_key = None
        self._linear_data = None
        # damping carried over between frames, one per path: the scale suited to a full step and to
        # a truncated one differ
        self._lam = self._lam_exact = None
        self._cg_per_step = None  # CG iterations per Gauss-Newton step over the last frames ("adaptive")
        # ratio of successive steps' decreases over the last frames, per preconditioner (the "remaining" rule; a
        # new dict on each update, so a copy of the state stays as it was)
        self._contraction = {}

    @property
    def factor(self) -> ReusedCholesky:
        """The full system's reused Cholesky ("exact"), analysed on first use."""
        if self._factor is None:
            self._factor = ReusedCholesky(self.system.matrix(np.ones(len(self.system.indices))), self._backend)
        return self._factor

    def energy(self, x: np.ndarray, targets: np.ndarray, active: np.ndarray) -> float:
        """E (Eq. 8) at x (N, 12)."""
        sysm, w, cons = self.system, self.system.weights, self.system.constraints
        return energy_gradient(np.ascontiguousarray(x, dtype=np.float64), sysm.g, sysm.edges, cons.nodes,
                               cons.weights, cons.points, np.ascontiguousarray(targets, dtype=np.float64),
                               np.ascontiguousarray(active, dtype=np.float64), sysm.bridges, w.rot, w.reg, w.con,
                               w.rig, self._no_gradient, False)

    @property
    def backend(self) -> str:
        return self.split.backend if self.split is not None else self.factor.backend

    def _linear(self, active: np.ndarray) -> np.ndarray:
        key = active.tobytes()
        if key != self._active_key:
            self._linear_data = self.system.const_data + self.system.constraint_data(active)
            self._active_key = key
        return self._linear_data

    def solve(self, x0: np.ndarray, targets: np.ndarray, active: np.ndarray,
              guess: np.ndarray | None = None, stop=None, before: np.ndarray | None = None) -> SolveReport:
        """Minimise E from x0 (N, 12) for constraint targets (L, 3) scaled by `active` (L,).

        `guess` (N, 12), e.g. a pose extrapolated from the last frames, replaces x0 as the start when
        its energy is lower; `before` (N, 12), the pose one solve before x0, gives the constant-velocity
        guess 2 x0 − before (made inside the PCG frame's numba call: `fast/gauss_newton.py`). `stop()`, asked after
        each step of a jump frame's exact solve, says a newer
        frame is waiting: the frame then ends there (E lowered or, after a rejected step, the damping
        raised; not converged) and the next frames go on with exact steps until the jump's budget is spent
        or it converges, so a live solve never holds one frame for the whole budget. A `Yield` (`fast/live_stop.py`) also ends a PCG frame after an accepted step (read
        inside the numba loop); the next frame goes on from its pose. Either way `SolveReport.stopped`.
        """
        s = self.settings
        if s.method == "pcg" and guess is None and self._last_energy is not None and not self._jump_left:
            # the usual frame: start, jump test and steps in one numba call
            threshold = s.jump * max(self._last_energy, self.energy_floor)
            factored = self.split.factorisations
            report = self._solve_pcg(x0, targets, active, stop=stop, before=before, threshold=threshold)
            if report.iterations >= 0:
                self._last_energy = report.energy
                return report
            x0, e0 = report.x, report.energy  # a jump: its start, taken on below
            factored = self.split.factorisations - factored  # a new tracked set's factor, made for the test
        else:
            factored = 0
            if guess is None and before is not None:
                guess = 2.0 * x0 - before
            e0 = self.energy(x0, targets, active)
            if guess is not None:
                e_guess = self.energy(guess, targets, active)
                if e_guess < e0:
                    x0, e0 = guess, e_guess
        if self.settings.method == "exact":
            return self._solve_exact(x0, targets, active)
        threshold = None if self._last_energy is None else self.settings.jump * max(self._last_energy,
                                                                                     self.energy_floor)
        jump = threshold is not None and e0 > threshold
        if jump:  # a teleport is mostly a rigid motion: start from it when it fits better (rigid_start.py)
            rigid = rigid_start(x0, self.system.g, self.system.constraints, targets, active)
            e_rigid = self.energy(rigid, targets, active) if rigid is not None else np.inf
            if e_rigid < e0:
                x0, e0 = rigid, e_rigid
                jump = e0 > threshold
        if self._last_energy is None:
            report = self._solve_exact(x0, targets, active)
        elif jump and self.settings.jump_steps == "pcg":
            lam = self._lam  # the jump's damping is not the scale of the frames after it
            report = self._solve_pcg(x0, targets, active, 2 * self.settings.max_iterations, stop)
            self._lam = lam
            if factored:
                report = replace(report, factorisations=report.factorisations + factored)
        elif self._jump_left or jump:
            # far from the warm start (a skeleton teleporting): twice the steps, else the frame can end
            # well above the minimum of the exact method, whose damping carries over from frame to frame
            budget = self._jump_left or 2 * self.settings.max_iterations
            report = self._solve_exact(x0, targets, active, budget, stop)
            self._jump_left = max(budget - report.iterations, 0) if report.stopped else 0
        else:
            report = self._solve_pcg(x0, targets, active, stop=stop)
        self._last_energy = report.energy
        return report

    def _solve_exact(self, x0: np.ndarray, targets: np.ndarray, active: np.ndarray,
                     max_iterations: int | None = None, stop=None) -> SolveReport:
        s = self.settings
        stopped = False
        max_iterations = max_iterations or s.max_iterations
        sysm = self.system
        linear = self._linear(active)
        x = x0.copy()
        parts = sysm.residuals(x, targets, active)
        energy = sysm.energy(parts)
        energies = [energy]
        # damping carries over from the previous frame: its scale is a property of the rig
        lam = self._lam_exact if self._lam_exact is not None else s.initial_damping
        nu = 2.0
        iterations = factorisations = accepted = 0
        while iterations < max_iterations and energy > self.energy_floor:
            data, grad = sysm.system(x, parts, linear, active)
            diag = data[sysm.diag_pos]
            floor = 1e-9 * max(diag.max(), 1e-300)
            # A Jacobi estimate of what a full step could still gain: when it is negligible the
            # pose is converged and no factorisation is spent confirming it.
            if grad @ (grad / np.maximum(diag, floor)) <= 1e-2 * s.relative_tolerance * energy:
                break
            stepped = False
            while iterations < max_iterations:
                iterations += 1
                damped = data.copy()
                damped[sysm.diag_pos] += lam * np.maximum(diag, floor)
                factorisations += 1
                try:
                    delta = self.factor.solve(sysm.matrix(damped), -grad)
                except NotPositiveDefinite:
                    lam = min(max(lam * 10.0, 1e-6), s.max_damping)
                    continue
                predicted = -(grad @ delta)  # the GN model's decrease, up to the damping term
                if predicted <= 1e-3 * s.relative_tolerance * energy:
                    break
                x_new = x + delta.reshape(x.shape)
                parts_new = sysm.residuals(x_new, targets, active)
                e_new = sysm.energy(parts_new)
                if np.isfinite(e_new) and e_new < energy:
                    decrease = energy - e_new
                    # Nielsen's update from the gain ratio: a step the model predicted well
                    # lowers the damping, a poor one keeps it
                    rho = decrease / max(predicted, 1e-300)
                    lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-12)
                    nu = 2.0
                    x, parts, energy = x_new, parts_new, e_new
                    energies.append(energy)
                    accepted += 1
                    stepped = True
                    break
                lam *= nu
                nu *= 2.0
                if lam > s.max_damping:
                    break
                if stop is not None and stop():  # a rejected step: the raised damping carries over
                    stopped = True
                    break
            if stopped or not stepped or decrease <= s.relative_tolerance * energies[-2]:
                break
            if stop is not None and stop():
                stopped = True
                break
        self._lam_exact = min(max(lam, s.initial_damping), 1e3)
        return SolveReport(x=x, energy=energy, iterations=iterations, accepted=accepted,
                           energies=tuple(energies), factorisations=factorisations,
                           stopped=stopped and iterations < max_iterations)

    def _solve_pcg(self, x0: np.ndarray, targets: np.ndarray, active: np.ndarray,
                   max_iterations: int | None = None, stop=None, before: np.ndarray | None = None,
                   threshold: float = np.inf) -> SolveReport:
        """The same damped Gauss-Newton loop, each step from a few preconditioned CG iterations, from x0 or
        the constant-velocity guess 2 x0 − `before` when its E is lower. Only a `Yield` stop can end it early:
        the loop is one numba call. A start above `threshold` is a jump: then no step is taken, the report's
        `iterations` is -1 and its x and energy are the start."""
        s = self.settings
        max_iterations = max_iterations or s.max_iterations
        sysm = self.system
        w = sysm.weights
        cons = sysm.constraints
        before_count = self.split.factorisations
        k, fac, k_blocks, kc, k_diag = self.split.frame_data(active)
        x = np.empty((sysm.n // 12, 12))
        lam = self._lam if self._lam is not None else s.initial_damping
        kind, coarse = self._preconditioner()
        tier = -1 if coarse else kind  # whose steps' contraction the "remaining" rule assumes
        flag, after = (stop.flag, stop.after) if isinstance(stop, Yield) else (NO_FLAG, 0.0)
        energy, iterations, accepted, cg_total, count, lam, ratio, stopped = pcg_frame(
            x, np.ascontiguousarray(x0, dtype=np.float64), self._no_pose if before is None else before, threshold,
            sysm.g, sysm.edges, cons.nodes, cons.weights, cons.points, np.ascontiguousarray(targets, dtype=np.float64),
            np.ascontiguousarray(active, dtype=np.float64), sysm.bridges, w.rot, w.reg, w.con, w.rig, kind, fac, k[0],
            k[1], k[2], k_blocks, k_diag, max_iterations, s.relative_tolerance, s.cg_iterations, s.cg_tolerance,
            lam, s.max_damping, self.energy_floor, self._rot, self._rig, self._node_fac, self._energies,
            s.backtracks, s.curvature, self._coarse if coarse else self._no_coarse, kc,
            self._contraction.get(tier, 1.0), s.remaining_tolerance if tier in REMAINING_TIERS else 0.0, flag, after,
            self._grad)
        if iterations < 0:
            return SolveReport(x=x, energy=energy, iterations=-1, accepted=0, factorisations=0, energies=())
        self._lam = min(max(lam, s.initial_damping), 1e3)
        if ratio > 0.0:
            self._contraction = {**self._contraction, tier: 0.5 * (self._contraction.get(tier, 1.0) + ratio)}
        if iterations and iterations < max_iterations and max_iterations == s.max_iterations:
            self._follow(cg_total / iterations)
        return SolveReport(x=x, energy=energy, iterations=iterations, accepted=accepted,
                           energies=tuple(self._energies[:count].tolist()),
                           factorisations=self.split.factorisations - before_count, cg_iterations=cg_total,
                           stopped=stopped)

    # "adaptive": above this many CG iterations per step (over the last frames) the two-level replaces the
    # half cycle; above COARSE_ON the coarse space joins in, and leaves below COARSE_OFF
    ADAPTIVE_CG_PER_STEP = 1.5
    COARSE_ON, COARSE_OFF = 2.0, 1.5

    def _follow(self, rate: float) -> None:
        """"adaptive": take a frame's CG iterations per Gauss-Newton step into the running rate, and decide
        whether the coarse space is in the next frames' preconditioner.

        Only frames that end within the usual step budget count: a jump's, or one that runs out of steps,
        is limited by the Gauss-Newton steps (a pose far from the warm start, the damping high), not by CG,
        and the coarse space does not help there. Its gain is in fewer steps per frame rather than fewer CG
        iterations per step.
        """
        self._cg_per_step = rate if self._cg_per_step is None else 0.5 * (self._cg_per_step + rate)
        if not self.settings.coarse_regions:
            return
        if self._coarse_on:
            self._coarse_on = self._cg_per_step > self.COARSE_OFF
        else:
            self._coarse_on = self._cg_per_step > self.COARSE_ON

    def _preconditioner(self) -> tuple[int, bool]:
        """The preconditioner for this frame, and whether the coarse space (`fast/coarse_space.py`) is in it.

        "adaptive" follows the CG iterations per Gauss-Newton step of the last frames (`_follow`; both
        designs need about as many on the same frames, so the choice does not flip with itself). At about
        one the half cycle: one pair of triangular solves per step instead of two. Above
        `ADAPTIVE_CG_PER_STEP` the two-level, whose steps need no restart. Above `COARSE_ON` graph-wide modes
        are what CG crawls on (one arm possessing a body) and the coarse space joins the two-level; where
        steps need about one CG iteration it would cost more per step than it saves in steps."""
        name, rate = self.settings.preconditioner, self._cg_per_step
        if name != "adaptive":
            return PRECONDITIONERS[name], self.settings.coarse_regions > 0
        if rate is not None and rate > self.ADAPTIVE_CG_PER_STEP:
            return TWO_LEVEL, self._coarse_on
        return HALF_CYCLE, False
