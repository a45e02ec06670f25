"""One-Euro filter on synthetic noisy signals, with numbers."""
from __future__ import annotations

import numpy as np
import pytest

from kinetre.errors import BadMotionError
from kinetre.motion.filters import OneEuroFilter, one_euro

FPS = 30.0


def test_first_step_is_the_textbook_alpha():
    # beta = 0: a plain low-pass with alpha = 1 / (1 + tau / dt), tau = 1 / (2 pi fc)
    f = OneEuroFilter(min_cutoff=1.0, beta=0.0)
    f(np.zeros(2), 0.0)
    alpha = 1.0 / (1.0 + (1.0 / (2 * np.pi)) * FPS)
    np.testing.assert_allclose(f(np.ones(2), 1 / FPS), [alpha, alpha], rtol=1e-12)


def test_jitter_at_rest_is_about_halved():
    rng = np.random.default_rng(1)
    noise = rng.normal(0.0, 0.01, size=(300, 20, 3))  # 1 cm jitter on every joint coordinate
    out = one_euro(noise, FPS)
    assert out.shape == noise.shape
    raw, smooth = noise[30:].std(), out[30:].std()
    assert smooth < 0.55 * raw, f"jitter {raw * 1000:.1f} mm -> {smooth * 1000:.1f} mm"


def test_slow_motion_tracks_closer_than_the_raw_samples():
    rng = np.random.default_rng(2)
    t = np.arange(300) / FPS
    truth = 0.2 * np.sin(2 * np.pi * 0.25 * t)  # a 20 cm, 4 s sway
    noisy = truth + rng.normal(0.0, 0.01, t.size)
    err_raw = np.sqrt(np.mean((noisy - truth)[30:] ** 2))
    err = np.sqrt(np.mean((one_euro(noisy, FPS) - truth)[30:] ** 2))
    assert err < 0.85 * err_raw, f"rms {err_raw * 1000:.1f} mm raw vs {err * 1000:.1f} mm filtered"


def test_fast_motion_has_less_lag_than_a_plain_low_pass():
    t = np.arange(90) / FPS
    step = np.where(t >= 1.0, 0.5, 0.0)  # a 50 cm jump at t = 1 s
    euro = one_euro(step, FPS)
    plain = one_euro(step, FPS, beta=0.0)
    k = 30 + 3  # 0.1 s after the jump
    assert euro[k] > 0.4 and plain[k] < 0.4
    assert abs(euro[-1] - 0.5) < 1e-3  # settles


def test_untracked_samples_pass_as_nan_and_restart():
    f = OneEuroFilter()
    f(np.array([0.0, 0.0]), 0.0)
    f(np.array([0.1, 0.1]), 1 / FPS)
    out = f(np.array([np.nan, 0.2]), 2 / FPS)
    assert np.isnan(out[0]) and np.isfinite(out[1])
    out = f(np.array([5.0, 0.3]), 3 / FPS)
    assert out[0] == 5.0  # a reappearing joint starts where it is seen, it does not glide


def test_bad_parameters():
    with pytest.raises(BadMotionError, match="min_cutoff must be a positive number"):
        OneEuroFilter(min_cutoff=0.0)
