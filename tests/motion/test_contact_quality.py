"""Quality figures, stance, floor and foot locking on synthetic takes with known answers: a planted foot with
tracker noise and drift, a walk with known stance phases, a jump."""
from __future__ import annotations

import numpy as np
import pytest

import kinetre
from kinetre.motion.cleanup import CleanupSettings, LiveCleaner, clean_take, clean_track
from kinetre.motion.contact import Floor, contact_joints, detect_stance, fit_floor, two_bone_ik
from kinetre.motion.quality import jitter, lag_ms, measure, take_quality
from kinetre.motion.stream import read_stream, write_stream
from kinetre.motion.take import Take, is_camera_take
from synthetic import tpose

K = kinetre.KINECT20
J = K.index
FPS = 30.0
FEET = (J("FootLeft"), J("FootRight"))


def standing(frames: int, centre=(0.0, 0.0, -3.0)) -> np.ndarray:
    """(T, 20, 3) a person standing with slightly bent knees, feet on y = 0, swaying their upper body."""
    base = tpose(1.7, centre).positions.copy()
    for knee in ("KneeLeft", "KneeRight"):
        base[J(knee), 2] += 0.04
    t = np.arange(frames) / FPS
    pos = np.repeat(base[None], frames, axis=0)
    upper = [J(n) for n in K.joints if not any(s in n for s in ("Hip", "Knee", "Ankle", "Foot"))]
    pos[:, upper, 0] += 0.05 * np.sin(2 * np.pi * 0.5 * t)[:, None]
    return pos


def noisy(pos: np.ndarray, seed: int = 0, noise: float = 0.015, drift: float = 0.06) -> np.ndarray:
    """Tracker-like errors: white noise per joint, and the whole body wandering in depth and sideways."""
    rng = np.random.default_rng(seed)
    t = np.arange(len(pos)) / FPS
    wander = np.stack([0.3 * drift * np.sin(2 * np.pi * 0.7 * t), 0.2 * drift * np.sin(2 * np.pi * 1.1 * t + 1),
                       drift * np.sin(2 * np.pi * 0.4 * t + 2)], axis=1)
    return pos + wander[:, None] + rng.normal(0.0, noise, pos.shape)


def camera_take(pos: np.ndarray) -> Take:
    return Take(K, pos, np.ones(pos.shape[:2], bool), FPS, "camera 0")


def test_quality_figures_have_known_answers():
    t = np.arange(60) / FPS
    pos = np.zeros((60, 2, 3))
    pos[:, 0, 1] = 0.5 * 2.0 * t ** 2             # 2 m/s^2 upwards, exactly
    assert jitter(pos, FPS)[0] == pytest.approx(2.0, rel=1e-9)
    assert jitter(pos, FPS, noise_only=True)[0] == pytest.approx(0.0, abs=1e-6)
    # a foot in stance sliding at 10 cm/s along x: skate speed 10 cm/s, slide 10 cm/s * duration
    pos[:, 0] = 0.0
    pos[:, 1] = np.stack([0.1 * t, np.zeros(60), np.zeros(60)], axis=1)
    from kinetre.motion.contact import Stance
    stance = Stance((1,), np.ones((60, 1), bool), Floor(0.0), np.zeros(1))
    q = measure(pos, FPS, (1,), ("foot",), stance)
    assert q.skate_speed == pytest.approx(10.0, rel=1e-6)
    assert q.slide == pytest.approx(100 * 0.1 * 59 / FPS, rel=1e-6)
    assert q.airborne == 0 and q.stance == 1.0
    # a signal delayed by 2 frames lags by 66.7 ms
    x = np.sin(2 * np.pi * 0.8 * np.arange(200) / FPS)[:, None]
    assert lag_ms(np.roll(x, 2, axis=0)[10:], x[10:], FPS) == pytest.approx(2000 / FPS, abs=3.0)


def test_two_bone_ik_reaches_and_keeps_lengths():
    root, mid, end = np.array([[0.0, 1.0, 0.0]]), np.array([[0.0, 0.55, 0.05]]), np.array([[0.0, 0.1, 0.0]])
    target = np.array([[0.1, 0.15, 0.12]])
    new_mid, new_end = two_bone_ik(root, mid, end, target)
    assert np.allclose(new_end, target)
    assert np.linalg.norm(new_mid - root) == pytest.approx(np.linalg.norm(mid - root))
    assert np.linalg.norm(new_end - new_mid) == pytest.approx(np.linalg.norm(end - mid))
    line = root + (target - root) * ((new_mid - root) @ (target - root).T) / np.sum((target - root) ** 2)
    assert new_mid[0, 2] > line[0, 2] + 0.02  # the knee still bends forwards


def test_floor_is_fitted_robustly_and_tilted_when_spread():
    rng = np.random.default_rng(1)
    xz = rng.uniform(-2, 2, (300, 2))
    y = 0.05 * xz[:, 0] - 0.02 * xz[:, 1] + 0.3 + rng.normal(0, 0.005, 300)
    y[:30] += 0.5  # outliers: a foot held up
    floor = fit_floor(np.column_stack([xz[:, 0], y, xz[:, 1]]))
    assert floor.height == pytest.approx(0.3, abs=0.01)
    assert floor.slope == pytest.approx((0.05, -0.02), abs=0.01)


def test_planted_feet_with_noise_and_drift_are_held():
    truth = standing(150)
    take = camera_take(noisy(truth))
    assert is_camera_take(take)
    clean = clean_take(take)
    stance = detect_stance(clean.positions, FPS, FEET)
    assert stance.mask.mean() > 0.9, "standing feet are in stance"
    before, after = take_quality(take, stance), take_quality(clean, stance, reference=take)
    assert before.slide_p95 > 3.0, before
    assert after.slide_p95 <= 1.0 and after.bob_p95 <= 1.0, after
    assert after.jitter <= before.jitter / 2
    assert abs(after.lag_ms) <= 1000 / FPS
    assert clean.applied["contact"]["joints"] == ["FootLeft", "FootRight"]
    assert clean.applied["smoothing"]["pass"] == "forward-backward"


def walk(frames: int = 150, speed: float = 1.0, cycle: float = 1.0, lift: float = 0.12):
    """A synthetic walk along -z: each foot planted 60 % of a cycle, then swinging in an arc to its next
    place. Returns positions and the true stance mask (T, 2)."""
    t = np.arange(frames) / FPS
    base = tpose(1.7, (0.0, 0.0, 0.0)).positions
    pos = np.repeat(base[None], frames, axis=0)
    pos[:, :, 2] -= speed * t[:, None]
    stance = np.zeros((frames, 2), bool)
    step = speed * cycle
    for side, (foot, ankle, phase0) in enumerate(((J("FootLeft"), J("AnkleLeft"), 0.0),
                                                   (J("FootRight"), J("AnkleRight"), 0.5))):
        phase = (t / cycle + phase0) % 1.0
        k = np.floor(t / cycle + phase0)
        planted = phase < 0.6
        z_hold = -step * k + base[foot, 2]
        swing = np.clip((phase - 0.6) / 0.4, 0, 1)
        z = np.where(planted, z_hold, z_hold - step * swing)
        y = np.where(planted, 0.0, lift * np.sin(np.pi * swing))
        pos[:, foot, 2], pos[:, foot, 1] = z, y
        pos[:, ankle, 2], pos[:, ankle, 1] = z - 0.1, y + 0.07
        knee = J("KneeLeft") if side == 0 else J("KneeRight")
        pos[:, knee] = (pos[:, ankle] + pos[:, J("HipLeft") if side == 0 else J("HipRight")]) / 2
        pos[:, knee, 2] -= 0.05
        stance[:, side] = planted
    return pos, stance


def test_walk_stance_phases_are_found():
    pos, truth = walk()
    got = detect_stance(pos, FPS, FEET).mask
    assert (got == truth).mean() > 0.85, f"stance agrees on {(got == truth).mean():.2f} of foot-frames"
    # with tracker noise, after cleaning, stance still follows the gait
    clean = clean_track(K, noisy(pos, seed=3, drift=0.0), FPS)
    assert (clean.stance.mask == truth).mean() > 0.85
    q = measure(clean.positions, FPS, FEET, stance=clean.stance)
    assert q.slide_p95 <= 1.0


def jump(frames: int = 120, start: int = 40, stop: int = 62, peak: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Standing, a jump of `peak` metres over frames [start, stop), standing again."""
    pos = standing(frames, (0.0, 0.0, 0.0))
    s = np.zeros(frames)
    u = (np.arange(start, stop) - start + 0.5) / (stop - start)
    s[start:stop] = 4 * peak * u * (1 - u)
    pos[:, :, 1] += s[:, None]
    air = np.zeros(frames, bool)
    air[start:stop] = True
    return pos, air


def test_a_jump_is_kept():
    pos, air = jump()
    take = Take(K, pos, np.ones(pos.shape[:2], bool), FPS, "jump.bvh")
    assert not is_camera_take(take)
    clean = clean_take(take, CleanupSettings(smooth=False))
    stance = detect_stance(pos, FPS, FEET)
    assert abs(int(stance.airborne().sum()) - int(air.sum())) <= 2
    after = detect_stance(clean.positions, FPS, FEET).airborne()
    assert np.flatnonzero(after)[[0, -1]] == pytest.approx(np.flatnonzero(air)[[0, -1]], abs=1)
    assert np.allclose(clean.positions[air], pos[air])  # in the air: untouched
    assert clean.positions[:, 0, 1].max() == pytest.approx(pos[:, 0, 1].max(), abs=0.02)


def test_a_noisy_jump_keeps_its_height_and_timing():
    pos, air = jump()
    clean = clean_take(camera_take(noisy(pos + [0, 0, -3.0], seed=5, drift=0.02)))
    got = detect_stance(clean.positions, FPS, FEET).airborne()
    first, last = np.flatnonzero(got)[[0, -1]]
    assert abs(first - 40) <= 1 and abs(last - 61) <= 1
    hip = clean.positions[:, 0, 1]
    assert hip.max() - np.median(hip) == pytest.approx(0.3, abs=0.03)


def test_applied_is_written_and_read(tmp_path):
    clean = clean_take(camera_take(noisy(standing(40))))
    path = tmp_path / "t.kinetre.jsonl"
    write_stream(path, clean)
    back = read_stream(path)
    assert back.applied["contact"]["joints"] == ["FootLeft", "FootRight"]
    assert back.applied["smoothing"]["joints"]["HipCenter"]["min_cutoff"] > 0
    assert np.allclose(back.positions, clean.positions)


def test_live_cleaner_holds_a_planted_foot_causally():
    truth = standing(150)
    raw = noisy(truth, seed=2, drift=0.0, noise=0.01)
    live = LiveCleaner(K)
    out = np.stack([live(raw[i], i / FPS) for i in range(len(raw))])
    stance = detect_stance(out, FPS, FEET)
    assert stance.mask[30:].mean() > 0.9
    before, after = measure(raw, FPS, FEET, stance=stance), measure(out, FPS, FEET, stance=stance, reference=raw)
    assert after.slide_p95 < before.slide_p95 / 2
    assert after.jitter < before.jitter / 2


def test_contact_joints_of_other_skeletons_are_the_lowest_leaves():
    model = kinetre.skeleton.models.SkeletonModel("quad", ("body", "fl", "fr", "bl", "br", "head"),
                                                  (-1, 0, 0, 0, 0, 0))
    pos = np.array([[0, 1, 0], [0.2, 0, 0.3], [-0.2, 0, 0.3], [0.2, 0, -0.3], [-0.2, 0, -0.3], [0, 1.2, 0.5]],
                   float)[None].repeat(3, axis=0)
    assert contact_joints(model, pos) == (1, 2, 3, 4)
    assert contact_joints(K, standing(3)) == FEET


def test_room_floor_and_live_meter():
    from kinetre.motion.cleanup import RoomFloor
    from kinetre.motion.quality import LiveMeter
    room = RoomFloor()
    people = [LiveCleaner(K, viewpoint=np.zeros(3), room=room) for _ in range(2)]
    raws = [noisy(standing(120, (x, 0.0, -3.0)), seed=k, drift=0.02, noise=0.01) for k, x in enumerate((-0.6, 0.6))]
    meter = LiveMeter()
    for i in range(120):
        for k, (c, raw) in enumerate(zip(people, raws)):
            out = c(raw[i], i / FPS)
            if k == 0:
                held, hold = c.held()
                stray = np.linalg.norm(out[list(c.joints)] - hold, axis=1)
                meter.add(raw[i], out, i / FPS, held, stray)
    # both stand on y = 0: one floor through everyone's feet
    assert np.abs(room.floor.above(np.array([[-0.6, 0.0, -3.0], [0.6, 0.0, -3.0]]))).max() < 0.02
    fig = meter.figures()
    assert fig["frames"] == 90 and fig["fps"] == FPS  # the last 3 s
    assert fig["jitter"] < fig["jitter_tracked"] / 2 and abs(fig["lag_ms"]) <= 1000 / FPS
    assert fig["held"] > 0.9 and fig["stray_cm"] <= 1.0


def test_a_slow_camera_still_gets_a_lag_figure():
    """At 2 frames a second, 3 s hold 6 frames, too few to measure a lag: the meter keeps its last 12 frames,
    and finds the one-frame delay of a motion shifted by one frame."""
    from kinetre.motion.quality import LiveMeter
    t = np.arange(40) / 2.0
    raw = np.stack([np.sin(0.9 * t + k)[:, None] * np.ones(3) for k in range(4)], axis=1)  # (T, 4, 3)
    late = np.concatenate([raw[:1], raw[:-1]])
    meter = LiveMeter()
    for i in range(len(t)):
        meter.add(raw[i], late[i], t[i])
    fig = meter.figures()
    assert fig["frames"] == 12 and fig["fps"] == 2.0
    assert abs(fig["lag_ms"] - 500) < 60
