"""The One-Euro filter (Casiez, Roussel & Vogel, CHI 2012): low lag when moving, little jitter at rest.

Per scalar, with sampling interval dt:

    alpha(fc) = 1 / (1 + tau / dt),  tau = 1 / (2 pi fc)
    dx_hat    = alpha(d_cutoff) * (x - x_hat_prev) / dt + (1 - alpha(d_cutoff)) * dx_hat_prev
    fc        = min_cutoff + beta * |dx_hat|
    x_hat     = alpha(fc) * x + (1 - alpha(fc)) * x_hat_prev

Vectorised: one filter state per element of an array of any shape (e.g. (J, 3) joint positions). A
non-finite sample (an untracked joint) passes through as NaN and restarts that element's filter when
it comes back, so a joint that reappears elsewhere does not glide there.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BadMotionError


class OneEuroFilter:
    """A bank of One-Euro filters over arrays of one shape.

    Parameters
    ----------
    min_cutoff : float
        Cutoff frequency at rest, Hz: lower removes more jitter when still.
    beta : float
        Speed coefficient, cutoff Hz per (unit / s): higher follows fast motion with less lag. The
        defaults suit joint positions in metres at 30 fps: on 1 cm noise they about halve the jitter at rest
        and track a 0.25 Hz, 20 cm sway closer than the raw samples (tests/motion/test_filters.py).
    d_cutoff : float
        Cutoff frequency of the speed estimate, Hz.

    Examples
    --------
    >>> f = OneEuroFilter(min_cutoff=1.0, beta=0.0)
    >>> float(f(np.array([0.0]), 0.0)[0]), round(float(f(np.array([1.0]), 1 / 30)[0]), 4)
    (0.0, 0.1732)
    """

    def __init__(self, min_cutoff=1.0, beta=20.0, d_cutoff=1.0):
        # each parameter is a number, or an array broadcasting against the samples (one per joint: (J, 1))
        for name, value in (("min_cutoff", min_cutoff), ("beta", beta), ("d_cutoff", d_cutoff)):
            v = np.asarray(value, dtype=np.float64)
            if not (np.isfinite(v).all() and (v >= 0).all()) or (name != "beta" and (v == 0).any()):
                raise BadMotionError(f"OneEuroFilter: {name} must be a positive number, got {value!r}")
        scalar = lambda v: float(v) if np.ndim(v) == 0 else np.asarray(v, dtype=np.float64)  # noqa: E731
        self.min_cutoff, self.beta, self.d_cutoff = scalar(min_cutoff), scalar(beta), scalar(d_cutoff)
        self._x = None   # last filtered value, NaN where the element has no state
        self._dx = None  # last filtered speed
        self._t = None

    @staticmethod
    def _alpha(cutoff, dt):
        tau = 1.0 / (2.0 * np.pi * cutoff)
        return 1.0 / (1.0 + tau / dt)

    def reset(self) -> None:
        self._x = self._dx = self._t = None

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        """Filter sample `x` (any shape, float) taken at time `t` seconds; returns the same shape."""
        x = np.asarray(x, dtype=np.float64)
        if self._x is None or self._x.shape != x.shape or t <= self._t:
            self._x = x.copy()
            self._dx = np.zeros_like(x)
            self._t = float(t)
            return x.copy()
        dt = float(t) - self._t
        self._t = float(t)
        ok = np.isfinite(x)
        fresh = ok & ~np.isfinite(self._x)  # reappearing elements start over
        dx = np.where(ok & ~fresh, (x - self._x) / dt, 0.0)
        a_d = self._alpha(self.d_cutoff, dt)
        dx_hat = a_d * dx + (1.0 - a_d) * self._dx
        a = self._alpha(self.min_cutoff + self.beta * np.abs(dx_hat), dt)
        x_hat = a * x + (1.0 - a) * self._x
        x_hat = np.where(fresh, x, x_hat)
        self._x = np.where(ok, x_hat, np.nan)
        self._dx = np.where(ok & ~fresh, dx_hat, 0.0)
        return self._x.copy()


def one_euro(signal: np.ndarray, fps: float, min_cutoff=1.0, beta=20.0, d_cutoff=1.0) -> np.ndarray:
    """Filter a whole recording (T, ...) sampled at `fps`, frame by frame (causal, as live)."""
    f = OneEuroFilter(min_cutoff, beta, d_cutoff)
    signal = np.asarray(signal, dtype=np.float64)
    return np.stack([f(s, i / fps) for i, s in enumerate(signal)]) if len(signal) else signal.copy()


def one_euro_both_ways(signal: np.ndarray, fps: float, min_cutoff=1.0, beta=20.0, d_cutoff=1.0) -> np.ndarray:
    """Filter a whole recording forwards, then the result backwards: each pass delays by what the other
    advances, so the pair adds no lag (as filtfilt does for a linear filter). Offline only."""
    once = one_euro(signal, fps, min_cutoff, beta, d_cutoff)
    return one_euro(once[::-1], fps, min_cutoff, beta, d_cutoff)[::-1].copy()


@dataclass(frozen=True)
class EuroTuning:
    """One-Euro parameters per joint, set from a take's own noise and speed.

    noise : (J,) metres, the jitter's standard deviation per axis (residual of a smooth fit, robust)
    speed : (J,) metres per second, a joint's typical moving speed (75th percentile of the smooth fit's)
    min_cutoff, beta : (J,) the filter's parameters; d_cutoff : the speed estimate's cutoff (Hz)
    """

    noise: np.ndarray
    speed: np.ndarray
    min_cutoff: np.ndarray
    beta: np.ndarray
    d_cutoff: float

    def to_dict(self, joints: tuple[str, ...]) -> dict:
        return {name: {"min_cutoff": round(float(m), 4), "beta": round(float(b), 4),
                       "noise_cm": round(100 * float(n), 3)}
                for name, m, b, n in zip(joints, self.min_cutoff, self.beta, self.noise)}


def tune_one_euro(positions: np.ndarray, fps: float, rest_noise: float = 0.002, moving_cutoff: float = 6.0,
                  d_cutoff: float = 2.0) -> EuroTuning:
    """One-Euro parameters per joint of a (T, J, 3) take (Casiez et al.'s tuning, done from the data).

    At rest a first-order low-pass at fc keeps a fraction alpha / (2 - alpha) of white noise's variance,
    alpha = 1 / (1 + fps / (2 pi fc)); min_cutoff is the fc that brings the joint's measured noise down to
    `rest_noise` metres. beta raises the cutoff to `moving_cutoff` Hz at the joint's typical speed, where a
    first-order filter's lag is 1 / (2 pi fc) (27 ms at 6 Hz)."""
    from scipy.signal import savgol_filter
    pos = np.asarray(positions, dtype=np.float64)
    j = pos.shape[1]
    noise, speed = np.full(j, np.nan), np.full(j, np.nan)
    w = max(5, int(round(fps / 3)) | 1)
    seen = np.isfinite(pos).all(axis=2)
    whole = np.flatnonzero(seen.all(axis=0)) if len(pos) >= w else np.zeros(0, int)
    if len(whole):  # the joints tracked in every frame, in one pass (the live path retunes every second)
        fits = savgol_filter(pos[:, whole], w, 3, axis=0)
        res = (pos[:, whole] - fits).transpose(1, 0, 2).reshape(len(whole), -1)
        noise[whole] = 1.4826 * np.median(np.abs(res - np.median(res, axis=1, keepdims=True)), axis=1)
        speed[whole] = np.percentile(np.linalg.norm(np.diff(fits, axis=0), axis=2) * fps, 75, axis=0)
    for k in np.flatnonzero(~np.isin(np.arange(j), whole)):
        res, spd = [], []
        for a, b in _runs(seen[:, k]):
            if b - a < w:
                continue
            fit = savgol_filter(pos[a:b, k], w, 3, axis=0)
            res.append((pos[a:b, k] - fit).ravel())
            spd.append(np.linalg.norm(np.diff(fit, axis=0), axis=1) * fps)
        if res:
            r = np.concatenate(res)
            noise[k] = 1.4826 * np.median(np.abs(r - np.median(r)))
            speed[k] = np.percentile(np.concatenate(spd), 75)
    noise = np.where(np.isfinite(noise), noise, np.nanmedian(noise) if np.isfinite(noise).any() else rest_noise)
    speed = np.where(np.isfinite(speed), speed, np.nanmedian(speed) if np.isfinite(speed).any() else 0.5)
    ratio = np.clip(rest_noise / np.maximum(noise, 1e-9), 0.0, 1.0) ** 2
    alpha = 2 * ratio / (1 + ratio)
    top = 0.9 * moving_cutoff
    fc = np.clip(fps / (2 * np.pi) * alpha / np.maximum(1 - alpha, 1e-9), 0.3, top)
    beta = (moving_cutoff - fc) / np.maximum(speed, 0.05)
    return EuroTuning(noise, speed, fc, beta, float(d_cutoff))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))
