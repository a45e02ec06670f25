"""How clean a motion looks: jitter, foot skate, ground contact and lag, in the user's units.

* Jitter: mean |acceleration| (second differences times fps^2) over tracked joints, m/s^2; and the same of
  the residual after removing a smooth fit (a Savitzky-Golay cubic over about a third of a second), which
  is the noise alone.
* Foot skate: while a contact joint is in stance (`kinetre.motion.contact`), its horizontal speed (cm/s),
  the horizontal path it slides (cm, summed over the stance runs, per contact joint), and the 95th
  percentile of its distance from where each stance run holds it (the run's median, cm); the same
  vertically (its bob).
* Ground: depth below the joint's resting level on the floor (99th percentile over all frames, cm) and
  height above it in stance (95th percentile, cm).
* Lag: the time shift (ms) that best aligns the motion's velocities with a reference (the unfiltered take);
  positive when the motion is late.

Stance is detected on the motion unless given; compare two versions of one take (raw and cleaned)
with the same stance, so both are measured over the same frames.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .contact import Stance, StanceSettings, contact_joints, detect_stance, runs
from .filters import one_euro_both_ways, tune_one_euro
from .take import camera_viewpoint


@dataclass(frozen=True)
class Quality:
    """Figures of one motion; NaN where a figure does not apply (no stance, no reference)."""

    frames: int
    fps: float
    contacts: tuple[str, ...]
    jitter: float           # m/s^2
    jitter_noise: float     # m/s^2, after removing a smooth fit
    skate_speed: float      # cm/s, mean horizontal speed in stance
    slide: float            # cm, horizontal path in stance per contact joint
    slide_p95: float        # cm, distance from each stance run's hold point
    bob_p95: float          # cm, vertical distance from each stance run's hold point
    penetration: float      # cm below the floor
    floating: float         # cm above the floor in stance
    stance: float           # fraction of contact joint-frames in stance
    airborne: int           # frames with every contact joint off the floor
    lag_ms: float           # against the reference

    def to_dict(self) -> dict:
        out = asdict(self)
        out["contacts"] = list(self.contacts)
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else
                    (round(v, 4) if isinstance(v, float) else v)) for k, v in out.items()}

    def lines(self) -> list[str]:
        """Human-readable summary lines."""
        f = lambda v, unit: "n/a" if not np.isfinite(v) else f"{v:.2f} {unit}"  # noqa: E731
        out = [f"jitter {f(self.jitter, 'm/s²')} (noise after a smooth fit {f(self.jitter_noise, 'm/s²')})"]
        if self.contacts:
            out.append(f"contacts {', '.join(self.contacts)}: in stance {100 * self.stance:.0f} % of frames, "
                       f"{self.airborne} frames with all off the floor")
            out.append(f"foot skate: {f(self.skate_speed, 'cm/s')} in stance, slide {f(self.slide, 'cm')} per "
                       f"contact, p95 {f(self.slide_p95, 'cm')} from the hold point, bob p95 {f(self.bob_p95, 'cm')}")
            out.append(f"ground: penetration {f(self.penetration, 'cm')}, floating {f(self.floating, 'cm')} in stance")
        if np.isfinite(self.lag_ms):
            out.append(f"lag {self.lag_ms:.0f} ms against the unfiltered motion")
        return out


def _smooth_fit(x: np.ndarray, fps: float) -> np.ndarray:
    """A Savitzky-Golay cubic over about a third of a second along axis 0 of a NaN-free run."""
    from scipy.signal import savgol_filter
    w = max(5, int(round(fps / 3)) | 1)
    if len(x) < w:
        return x
    return savgol_filter(x, w, 3, axis=0, mode="interp")


def jitter(positions: np.ndarray, fps: float, noise_only: bool = False) -> np.ndarray:
    """(J,) mean |acceleration| per joint, m/s^2 (NaN for a joint never tracked three frames running);
    with `noise_only`, of the residual after a smooth fit."""
    pos = np.asarray(positions, dtype=np.float64)
    if noise_only:
        return _jitter_of_noise(pos, fps)
    # an acceleration needs three frames running tracked: the same triples a walk over each joint's runs takes
    acc = np.linalg.norm(pos[2:] - 2 * pos[1:-1] + pos[:-2], axis=2) * fps * fps  # (T-2, J), NaN off-track
    ok = np.isfinite(acc)
    count = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, np.where(ok, acc, 0.0).sum(axis=0) / count, np.nan)


def _jitter_of_noise(pos: np.ndarray, fps: float) -> np.ndarray:
    """`jitter` of each joint's residual after a smooth fit over each of its tracked runs."""
    out = np.full(pos.shape[1], np.nan)
    for j in range(pos.shape[1]):
        total, count = 0.0, 0
        for a, b in runs(np.isfinite(pos[:, j]).all(axis=1)):
            x = pos[a:b, j]
            if len(x) < 3:
                continue
            x = x - _smooth_fit(x, fps)
            acc = np.linalg.norm(x[2:] - 2 * x[1:-1] + x[:-2], axis=1) * fps * fps
            total, count = total + acc.sum(), count + len(acc)
        if count:
            out[j] = total / count
    return out


def lag_ms(motion: np.ndarray, reference: np.ndarray, fps: float, most: float = 0.5) -> float:
    """The shift (ms, sub-frame) that best aligns `motion`'s velocities with `reference`'s (both (T, ...)),
    positive when `motion` is late; NaN when nothing moves."""
    v = np.diff(np.asarray(motion, dtype=np.float64), axis=0).reshape(len(motion) - 1, -1)
    r = np.diff(np.asarray(reference, dtype=np.float64), axis=0).reshape(len(reference) - 1, -1)
    ok = np.isfinite(v) & np.isfinite(r)
    v, r = np.where(ok, v, 0.0), np.where(ok, r, 0.0)
    k = max(1, min(int(round(most * fps)), (len(v) - 1) // 3))
    if len(v) < 4 or not (v.any() and r.any()):
        return float("nan")
    shifts = np.arange(-k, k + 1)
    n = len(v)
    # the same central samples of `motion` against `reference` shifted back by s: v(t) ~ r(t - s)
    score = np.array([(v[k:n - k] * r[k - s:n - k - s]).sum() for s in shifts])
    i = int(np.argmax(score))
    best = float(shifts[i])
    if 0 < i < len(score) - 1:  # parabola through the peak and its neighbours
        den = score[i - 1] - 2 * score[i] + score[i + 1]
        if den < 0:
            best += 0.5 * (score[i - 1] - score[i + 1]) / den
    return 1000.0 * best / fps


def measure(positions: np.ndarray, fps: float, contacts: tuple[int, ...], names: tuple[str, ...] = (),
            stance: Stance | None = None, reference: np.ndarray | None = None,
            settings: StanceSettings = StanceSettings(), viewpoint: np.ndarray | None = None) -> Quality:
    """The quality of a motion (T, J, 3) metres, +Y up, whose contact points are `contacts` (indices of J).

    `stance` gives the stance frames and floor; without it stance is detected on the motion smoothed without
    lag (one_euro_both_ways; across the line of sight from a camera's `viewpoint`): raw tracker noise would
    hide the stance it is measured over. `reference` (T, J, 3) is the unfiltered motion, for the lag."""
    pos = np.asarray(positions, dtype=np.float64)
    if stance is None:
        tune = tune_one_euro(pos, fps)
        smooth = one_euro_both_ways(pos, fps, tune.min_cutoff[:, None], tune.beta[:, None], tune.d_cutoff)
        stance = detect_stance(np.where(np.isfinite(pos), smooth, np.nan), fps, contacts, settings,
                               viewpoint=viewpoint)
    jit, noise = jitter(pos, fps), jitter(pos, fps, noise_only=True)
    mean = lambda a: float(np.nanmean(a)) if np.isfinite(a).any() else float("nan")  # noqa: E731
    speeds, slides, dist, bob, floating, depth = [], [], [], [], [], []
    for c, j in enumerate(stance.joints):
        p = pos[:, j]
        height = stance.floor.above(p) - stance.level[c]
        depth.append(np.clip(-height[np.isfinite(height)], 0, None))
        path = 0.0
        for a, b in runs(stance.mask[:, c]):
            seg = p[a:b]
            seg = seg[np.isfinite(seg).all(axis=1)]
            if len(seg) < 2:
                continue
            step = np.linalg.norm(np.diff(seg[:, [0, 2]], axis=0), axis=1)
            speeds.append(step * fps)
            path += step.sum()
            hold = np.median(seg, axis=0)
            dist.append(np.linalg.norm(seg[:, [0, 2]] - hold[[0, 2]], axis=1))
            bob.append(np.abs(seg[:, 1] - hold[1]))
            h = height[a:b]
            floating.append(np.clip(h[np.isfinite(h)], 0, None))
        slides.append(path)
    cat = lambda xs: np.concatenate(xs) if xs and sum(map(len, xs)) else np.array([])  # noqa: E731
    pct = lambda xs, q: 100 * float(np.percentile(cat(xs), q)) if len(cat(xs)) else float("nan")  # noqa: E731
    speed = cat(speeds)
    lag = float("nan") if reference is None else lag_ms(pos, reference, fps)
    return Quality(
        frames=len(pos), fps=float(fps), contacts=tuple(names) or tuple(str(j) for j in stance.joints),
        jitter=mean(jit), jitter_noise=mean(noise),
        skate_speed=100 * float(speed.mean()) if len(speed) else float("nan"),
        slide=100 * float(np.mean(slides)) if slides and stance.mask.any() else float("nan"),
        slide_p95=pct(dist, 95), bob_p95=pct(bob, 95), penetration=pct(depth, 99), floating=pct(floating, 95),
        stance=float(stance.mask.mean()) if stance.mask.size else float("nan"),
        airborne=int(stance.airborne().sum()) if stance.joints else 0, lag_ms=lag)


def take_quality(take, stance: Stance | None = None, reference=None) -> Quality:
    """`measure` of a Take, its contact joints found from its model; `reference` a Take of the same frames."""
    joints = contact_joints(take.model, take.positions)
    ref = None if reference is None else reference.positions
    return measure(take.positions, take.fps, joints, tuple(take.model.joints[j] for j in joints), stance, ref,
                   viewpoint=camera_viewpoint(take))


class LiveMeter:
    """A user's live motion quality over the last `seconds`, or its last `least` frames when a slow camera gives
    fewer (the lag needs a few frames either side of a shift to be measured at all): jitter as tracked and as
    cleaned (m/s^2), the lag cleaning adds (ms), the share of frames with a foot held, and how far held feet
    stray from where they are held (95th percentile, cm).

    >>> m = LiveMeter()
    >>> m.add(np.zeros((20, 3)), np.zeros((20, 3)), 0.0)
    >>> m.figures()["frames"]
    1
    """

    def __init__(self, seconds: float = 3.0, least: int = 12):
        self.seconds, self.least = seconds, least
        self._t: list[float] = []
        self._raw: list[np.ndarray] = []
        self._clean: list[np.ndarray] = []
        self._held: list[bool] = []
        self._stray: list[float] = []

    def add(self, raw: np.ndarray, clean: np.ndarray, t: float, held: np.ndarray | None = None,
            stray: np.ndarray | None = None) -> None:
        """One frame: its (J, 3) joints as tracked and as cleaned at `t` seconds; `held` (C,) bool which contact
        joints are held and `stray` (C,) metres each is from its hold."""
        self._t.append(float(t))
        self._raw.append(np.asarray(raw, dtype=np.float64))
        self._clean.append(np.asarray(clean, dtype=np.float64))
        on = np.zeros(0, bool) if held is None else np.asarray(held, bool)
        self._held.append(bool(on.any()))
        self._stray.append(float(np.max(np.asarray(stray)[on])) if on.any() and stray is not None else np.nan)
        while len(self._t) > self.least and self._t[0] < t - self.seconds:
            for buf in (self._t, self._raw, self._clean, self._held, self._stray):
                del buf[0]

    def figures(self) -> dict:
        n = len(self._t)
        out = {"frames": n, "fps": None, "jitter_tracked": None, "jitter": None, "lag_ms": None, "held": None, "stray_cm": None}
        if n < 4:
            return out
        dt = np.diff(self._t)
        fps = float(1.0 / np.median(dt[dt > 0])) if (dt > 0).any() else 30.0
        raw, clean = np.stack(self._raw), np.stack(self._clean)
        mean = lambda a: round(float(np.nanmean(a)), 2) if np.isfinite(a).any() else None  # noqa: E731
        stray = np.array(self._stray)
        lag = lag_ms(clean, raw, fps, most=0.25) if n >= 8 else float("nan")
        out.update(fps=round(fps, 2), jitter_tracked=mean(jitter(raw, fps)), jitter=mean(jitter(clean, fps)),
                   lag_ms=round(lag, 1) if np.isfinite(lag) else None, held=round(float(np.mean(self._held)), 3),
                   stray_cm=round(100 * float(np.percentile(stray[np.isfinite(stray)], 95)), 2)
                   if np.isfinite(stray).any() else None)
        return out
