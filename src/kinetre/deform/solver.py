"""Gauss-Newton with Levenberg-Marquardt damping on the Eq. 8 energy, warm-started per frame.

Each iteration solves (JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr. By default (`method="pcg"`) with a few conjugate
gradient iterations preconditioned by the per-coordinate factor of the linear terms (`coordinate_split.py`,
`krylov.py`): no factorisation per frame, only triangular solves on a 4N system; its node blocks also
carry E_rot's own curvature where columns stretch (`krylov.stretch_curvature`). `method="exact"` solves
with a sparse Cholesky of the full 12N system, its symbolic analysis reused (the reference).
`method="local_global"` replaces the PCG loop by Anderson-accelerated local/global iterations on the same
factor (`local_global.py`), handing over to it when they stall.
A step that does not lower E is rejected and λ grows, so E never increases. The loop stops after
`max_iterations` steps, or as soon as an accepted step's decrease is negligible — checked before
factoring again, so no factorisation is spent only to confirm convergence.

With `reuse_factor` the numeric factor of an earlier iteration (or frame) is kept while its steps
keep lowering E, and refreshed when one does not: an inexact Newton step that trades a few more,
much cheaper iterations for far fewer factorisations (ours; see the benchmark).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .coordinate_split import CoordinateSplit
from .factor import NotPositiveDefinite, ReusedCholesky
from .gradient import energy_gradient
from .krylov import ADDITIVE, BLOCK_JACOBI, COORDINATE, HALF_CYCLE, TWO_LEVEL, V_CYCLE
from .live_stop import NO_FLAG, Yield
from .local_global import LocalGlobalSettings
from .local_global import solve_frame as local_global_frame
from .pcg_frame import pcg_frame
from .normal_equations import NormalEquations
from .rigid_start import rigid_start

# the preconditioners whose frames end by the "remaining" rule (coarse-space frames end by "decrease")
REMAINING_TIERS = (HALF_CYCLE, TWO_LEVEL)

PRECONDITIONERS = {"coordinate": COORDINATE, "block_jacobi": BLOCK_JACOBI, "two_level": TWO_LEVEL, "additive": ADDITIVE,
                   "v_cycle": V_CYCLE, "half_cycle": HALF_CYCLE, "adaptive": HALF_CYCLE}


@dataclass(frozen=True)
class SolverSettings:
    """How `Rig.solve` minimises E per frame.

    method : "pcg" (default), "exact" (sparse Cholesky of the full system, the reference) or
        "local_global" (`local_global.py`, settings in `local_global`; jumps and the first frame as "pcg")
    preconditioner : for "pcg": "adaptive" (default: "half_cycle" while the last frames' Gauss-Newton steps
        needed about one CG iteration each, else "two_level": see `GaussNewton._preconditioner`),
        "half_cycle" (node blocks then K_σ for a step's first CG iteration, then
        "two_level": one pair of triangular solves where most steps need only that iteration),
        "two_level" (K_σ, node blocks, K_σ), "v_cycle" (node blocks, K_σ, node
        blocks: one pair of triangular solves per application instead of two, but at 512 nodes twice the
        iterations), "additive" (K_σ + node blocks),
        "coordinate" (K_σ only) or "block_jacobi" (node blocks, plus the coarse space unless
        `coarse_regions` is 0); see `krylov.py`. Only K_σ or the coarse space carry the
        graph-wide coupling: block Jacobi alone stalls when few nodes are constrained (one arm, 256 nodes:
        0.25 above the exact energy; with the coarse space 4e-5, and faster than the default there and at
        512 nodes with one skeleton, slower at 512 with two: bench_core)
    cg_iterations, cg_tolerance : CG iterations per Gauss-Newton step at most, and the relative
        residual that ends them earlier
    jump : for "pcg": a frame whose starting energy exceeds `jump` times the last solve's result (and
        the first solve) is a jump: its start is the best rigid motion of the pose onto the targets when
        that fits better (`rigid_start.py`); if it is still a jump it gets twice the steps, of `jump_steps`
    jump_steps : "pcg" (default) or "exact". From the rigid start PCG steps reach as low an energy as exact
        ones (bench_network's walk loop-around, 256 nodes: 5-20 instead of 85-134 ms CPU, lower E on the
        next frames); "exact" steps (without the rigid start, PCG steps can end in a worse local minimum) can
        be cut short by `stop` and go on over the next frames
    backtracks : for "pcg": halvings of a step that raised E tried before solving for a new one
    curvature : for "pcg": add E_rot's own curvature on stretched columns to the Gauss-Newton blocks
        (`krylov.stretch_curvature`): a Newton step where Gauss-Newton's would overshoot (two-level
        preconditioner, 256 nodes, two skeletons: 3.1 instead of 4.2 steps per frame on the walk)
    stop, remaining_tolerance : for "pcg", when a frame ends. "remaining" (default; on the half cycle's and the
        two-level's frames, the coarse space's end by "decrease"): after a full step whose CG met its tolerance, when it gained less than
        `relative_tolerance` or the next step would gain less than `remaining_tolerance` of E, estimated as
        this step's gain times the ratio of the last two steps' gains (linear convergence; on a frame's first
        step the ratio carried over from the last frames on the same preconditioner: the two-level's first steps
        gain far more of E than the half cycle's). "decrease": on a step that gained less than
        `relative_tolerance` (session 11's rule, the exact solve's): that step only confirms convergence, at a
        full step's cost. Measured from the same start as a tightly converged exact solve (bench_core
        `solve_agreement`), 256 nodes, two skeletons on the walk: 2.7 instead of 3.3 steps per frame, 27 %
        less CPU, median gap 2.7e-4 instead of 1.2e-4 (the exact solve's own stop: 1.8e-4, p95 4.2e-3). On
        the two-level's frames too (512 nodes, one skeleton, the adaptive choice: 3.9 instead of 4.25 steps per
        frame; the live two-legs Spot case, coarse space mostly on: as many CG iterations as before, 1171
        against 1160 in all, the same 12 frames out of steps)
    reuse_factor : for "exact": keep the numeric factor while its steps keep lowering E
    coarse_regions : for "pcg" with the half cycle, two-level or block Jacobi: a coarse space of this many regions' affine
        motions in the preconditioner (`coarse_space.py`), for whole limbs turning; 0: none. "adaptive"
        uses it only on frames whose steps need many CG iterations
    """

    max_iterations: int = 10
    relative_tolerance: float = 1e-3   # stop when an accepted step lowers E by less than this fraction
    initial_damping: float = 1e-6
    max_damping: float = 1e8
    reuse_factor: bool = False
    method: str = "pcg"
    preconditioner: str = "adaptive"
    cg_iterations: int = 8
    cg_tolerance: float = 0.2
    jump: float = 10.0
    jump_steps: str = "pcg"
    backtracks: int = 2
    local_global: LocalGlobalSettings = LocalGlobalSettings()
    curvature: bool = True
    coarse_regions: int = 8
    stop: str = "remaining"
    remaining_tolerance: float = 3e-4

    def __post_init__(self):
        if self.method not in ("pcg", "exact", "local_global"):
            raise ValueError(f"SolverSettings.method must be 'pcg', 'exact' or 'local_global', got {self.method!r}")
        if self.jump_steps not in ("pcg", "exact"):
            raise ValueError(f"SolverSettings.jump_steps must be 'pcg' or 'exact', got {self.jump_steps!r}")
        if self.stop not in ("remaining", "decrease"):
            raise ValueError(f"SolverSettings.stop must be 'remaining' or 'decrease', got {self.stop!r}")
        if self.preconditioner not in PRECONDITIONERS:
            raise ValueError(f"SolverSettings.preconditioner must be one of {sorted(PRECONDITIONERS)}, "
                             f"got {self.preconditioner!r}")


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
        self._node_fac = np.zeros((nodes, 12, 12))
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
        self._factored = False
        self._diag = None
        # damping carried over between frames, one per path: the scale suited to a full step and to
        # a truncated one differ
        self._lam = self._lam_exact = None
        self._cg_per_step = None  # CG iterations per Gauss-Newton step over the last frames ("adaptive")
        # ratio of successive steps' decreases over the last frames, per preconditioner (stop="remaining"; a new
        # dict on each update: bench_core restores it between timed runs)
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
            self._factored = False
        return self._linear_data

    def solve(self, x0: np.ndarray, targets: np.ndarray, active: np.ndarray,
              guess: np.ndarray | None = None, stop=None, before: np.ndarray | None = None) -> SolveReport:
        """Minimise E from x0 (N, 12) for constraint targets (L, 3) scaled by `active` (L,).

        `guess` (N, 12), e.g. a pose extrapolated from the last frames, replaces x0 as the start when
        its energy is lower; `before` (N, 12), the pose one solve before x0, gives the constant-velocity
        guess 2 x0 − before (made inside the PCG frame's numba call: `pcg_frame.py`). `stop()`, asked after
        each step of a jump frame's exact solve, says a newer
        frame is waiting: the frame then ends there (E lowered or, after a rejected step, the damping
        raised; not converged) and the next frames go on with exact steps until the jump's budget is spent
        or it converges, so a live solve never holds one frame for the whole budget (a 253-node jump: 20
        factorisations, ~100 ms). A `live_stop.Yield` also ends a PCG frame after an accepted step (read
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
        elif self.settings.method == "local_global":
            report = self._solve_local_global(x0, targets, active)
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
        reusable = s.reuse_factor and self._factored
        while iterations < max_iterations and energy > self.energy_floor:
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
            while iterations < max_iterations:
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
            self._contraction.get(tier, 1.0), s.remaining_tolerance if s.stop == "remaining" and tier in REMAINING_TIERS
            else 0.0, flag, after, self._grad)
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
        and the coarse space does not help there. Measured on the capsule body with two skeletons each
        driving one leg, 7 frames apart (bench_core's `solve_tail`): after the loop-around, frames out of
        steps at 2-2.5 CG iterations per step brought it in; with it they took the same 10 steps at 2.6-4.8
        CG iterations each (2.1-3 with its factor refreshed every step), which kept it on: 22-32 instead of
        12-18 ms CPU a frame. Its gain is in steps rather than in CG iterations per step (one arm: 2 steps a
        frame instead of 3-4, at 2-3.5 CG iterations each either way).
        """
        self._cg_per_step = rate if self._cg_per_step is None else 0.5 * (self._cg_per_step + rate)
        if not self.settings.coarse_regions:
            return
        if self._coarse_on:
            self._coarse_on = self._cg_per_step > self.COARSE_OFF
        else:
            self._coarse_on = self._cg_per_step > self.COARSE_ON

    def _preconditioner(self) -> tuple[int, bool]:
        """The preconditioner for this frame, and whether the coarse space (`coarse_space.py`) is in it.

        "adaptive" follows the CG iterations per Gauss-Newton step of the last frames (`_follow`; both
        designs need about as many on the same frames, so the choice does not flip with itself). At about
        one (the walk with two skeletons: 1.2) the half cycle: one pair of triangular solves per step
        instead of two. Above 1.5 the two-level, whose steps need no restart (512 nodes and one skeleton:
        1.45-1.5 per step, 3.6 steps per frame against the half cycle's 4.8; measured, the two about even in
        time, the half cycle 2-4 % slower in most runs). Above two, graph-wide modes are what CG crawls on
        (one arm possessing a body: 2.4-3.3) and the coarse space of `coarse_regions` regions joins the
        two-level: there 2.1 instead of 3.3-4.8 steps per frame, 3.2 instead of 4.1-4.5 CPU ms at 256
        nodes, and the exact solve's energies to 2e-5 instead of 1.2-1.4e-3 (median). On the walk with two
        skeletons it would cost 0.2 ms per step for 0.3 fewer steps, so it stays out there."""
        name, rate = self.settings.preconditioner, self._cg_per_step
        if name != "adaptive":
            return PRECONDITIONERS[name], self.settings.coarse_regions > 0 and name in ("half_cycle", "two_level", "block_jacobi")
        if rate is not None and rate > self.ADAPTIVE_CG_PER_STEP:
            return TWO_LEVEL, self._coarse_on
        return HALF_CYCLE, False

    def _solve_local_global(self, x0: np.ndarray, targets: np.ndarray, active: np.ndarray) -> SolveReport:
        """Local/global iterations (`local_global.py`), then the PCG loop from their result unless they
        converged."""
        before = self.split.factorisations
        x, energy, iterations, accepted, energies, converged = local_global_frame(
            self.system, self.split.frame_data(active), self.settings.local_global, x0,
            targets, active, self.energy_floor, self._rot, self._rig, self._node_fac)
        if converged:
            return SolveReport(x=x, energy=energy, iterations=iterations, accepted=accepted, energies=energies,
                               factorisations=self.split.factorisations - before)
        rest = self._solve_pcg(x, targets, active)
        return SolveReport(x=rest.x, energy=rest.energy, iterations=iterations + rest.iterations,
                           accepted=accepted + rest.accepted, energies=energies + rest.energies[1:],
                           factorisations=self.split.factorisations - before, cg_iterations=rest.cg_iterations)
