"""The Take interface: frames, slicing, transforms, resampling and the reader registry."""
from __future__ import annotations

import numpy as np
import pytest

import kinetre
from kinetre.errors import BadMotionError
from kinetre.motion.source import Take, load_take, resample


def ramp(frames=11, fps=10.0) -> Take:
    """Every coordinate of frame i equals i (a linear motion, easy to resample by hand)."""
    pos = np.repeat(np.arange(frames, dtype=float)[:, None, None], 20, axis=1).repeat(3, axis=2)
    return Take(kinetre.KINECT20, pos, np.ones((frames, 20), bool), fps, "ramp")


def test_take_shapes_and_frames():
    t = ramp()
    assert len(t) == 11 and t.duration == pytest.approx(1.0)
    f = t.frame(-1)
    assert isinstance(f, kinetre.Skeleton) and f.positions[0, 0] == 10.0
    with pytest.raises(BadMotionError, match="frame 11 out of range"):
        t.frame(11)
    with pytest.raises(BadMotionError, match=r"positions must be \(T, 20, 3\)"):
        Take(kinetre.KINECT20, np.zeros((3, 19, 3)), np.ones((3, 19), bool), 30.0)
    with pytest.raises(BadMotionError, match="fps must be a positive number"):
        Take(kinetre.KINECT20, np.zeros((3, 20, 3)), np.ones((3, 20), bool), float("nan"))
    with pytest.raises(BadMotionError, match="no frames"):
        Take(kinetre.KINECT20, np.zeros((0, 20, 3)), np.ones((0, 20), bool), 30.0)


def test_non_finite_positions_are_untracked():
    pos = np.zeros((2, 20, 3))
    pos[1, 4] = np.nan
    t = Take(kinetre.KINECT20, pos, np.ones((2, 20), bool), 30.0)
    assert t.tracked.sum() == 39 and not t.tracked[1, 4]


def test_slice_and_transform():
    t = ramp()
    s = t.slice(2, 8, 2)
    assert len(s) == 3 and s.fps == 5.0 and s.positions[1, 0, 0] == 4.0
    with pytest.raises(BadMotionError, match="select nothing"):
        t.slice(20, 30)
    r = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    m = t.transformed(2.0, r, (1.0, 0.0, 0.0))
    np.testing.assert_allclose(m.positions[3, 0], 2.0 * r @ [3.0, 3.0, 3.0] + [1.0, 0.0, 0.0])


def test_resample():
    t = ramp(frames=11, fps=10.0)
    down = resample(t, 5.0)  # integer ratio: every other frame, bits kept
    assert len(down) == 6 and np.array_equal(down.positions, t.positions[::2])
    up = resample(t, 25.0)  # 0.04 s steps: frame k sits at original index k * 0.4
    assert len(up) == 26
    np.testing.assert_allclose(up.positions[:, 0, 0], np.arange(26) * 0.4, atol=1e-12)
    tracked = t.tracked.copy()
    tracked[3, 0] = False
    gap = resample(Take(t.model, t.positions, tracked, 10.0), 20.0)
    # new frames touching original frame 3 (indices 5, 6, 7 -> orig 2.5, 3, 3.5) lose the joint
    assert gap.tracked[:, 0].tolist() == [True] * 5 + [False] * 3 + [True] * 13


def crowd_ramp(frames=11, fps=10.0) -> Take:
    """Two people whose joints, hands and blendshapes all equal the frame index (person 7 offset by 100);
    person 7's right hand and face are missing in frame 3."""
    base = ramp(frames, fps)
    i = np.arange(frames, dtype=float)
    crowd = np.stack([base.positions, base.positions + 100.0], axis=1)
    hands = np.broadcast_to(i[:, None, None, None, None], (frames, 2, 2, 21, 3)).copy()
    hands[:, 1] += 100.0
    hands[3, 1, 1] = np.nan
    faces = np.broadcast_to(i[:, None, None] / 10.0, (frames, 2, 3)).copy()
    faces[3, 1] = np.nan
    return Take(base.model, base.positions, base.tracked, fps, "crowd", (2, 7), crowd,
                np.ones((frames, 2, 20), bool), hands, faces, ("jawOpen", "eyeBlinkLeft", "mouthClose"))


def test_resample_keeps_people_hands_and_faces():
    t = crowd_ramp()
    down = resample(t, 5.0)
    assert down.people == (2, 7) and down.blendshape_names == t.blendshape_names and down.fps == 5.0
    assert np.array_equal(down.crowd_positions, t.crowd_positions[::2], equal_nan=True)
    assert np.array_equal(down.hands, t.hands[::2], equal_nan=True)
    assert np.array_equal(down.blendshapes, t.blendshapes[::2], equal_nan=True)
    up = resample(t, 25.0)  # frame k at original index 0.4 k
    x = np.arange(26) * 0.4
    np.testing.assert_allclose(up.crowd_positions[:, 1, 5, 2], x + 100.0, atol=1e-12)
    np.testing.assert_allclose(up.hands[:, 0, 0, 20, 1], x, atol=1e-12)
    np.testing.assert_allclose(up.blendshapes[:, 0, 2], x / 10.0, atol=1e-12)
    # between frames 2..4 person 7's right hand and face are gone; their left hand is not
    near3 = (x > 2.0) & (x < 4.0)
    assert np.isnan(up.hands[near3, 1, 1]).all() and np.isfinite(up.hands[~near3, 1, 1]).all()
    assert np.isnan(up.blendshapes[near3, 1]).all() and np.isfinite(up.blendshapes[~near3, 1]).all()
    assert np.isfinite(up.hands[:, 1, 0]).all() and up.crowd_tracked.all()
    assert np.array_equal(up.positions, resample(ramp(), 25.0).positions)


def test_load_take_picks_the_reader(data_dir, tmp_path):
    assert load_take(data_dir / "bvh" / "mocapbank_test.bvh").model is kinetre.KINECT20
    with pytest.raises(BadMotionError, match="unknown motion format"):
        load_take(tmp_path / "take.csv")
