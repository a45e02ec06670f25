"""Algorithm 1 on real avatars: rigid bones, bone directions as tracked, the bind pose reproduced by the
avatar's own skeleton, scaled root travel, tracking loss held, streaming = batch."""
from __future__ import annotations

import numpy as np
import pytest

from kinetre.avatar.bonemap import kinect_from_openni
from kinetre.avatar.retarget import RetargetState, retarget
from kinetre.skeleton.models import KINECT20, OPENNI17

from avatar.conftest import HUMANOIDS

K = KINECT20.index


def bone_directions_error(plan, bonemap, motion, positions, tracked):
    """Per followed bone, the largest angle (degrees) between the avatar's bone and the tracked one, over
    the frames where both ends are tracked (apart)."""
    avatar_of = {K(kj): j for kj, j in bonemap.joints.items()}
    src = positions @ plan.align.T
    worst = {}
    for j in np.flatnonzero(plan.aim_from >= 0):
        a, b = plan.aim_from[j], plan.aim_to[j]
        ok = tracked[:, a] & tracked[:, b] & (np.linalg.norm(src[:, b] - src[:, a], axis=1) > 1e-9)
        if not ok.any():                     # a zero-length source bone (CMU's hands) has no direction
            continue
        d = motion.positions[ok, avatar_of[b]] - motion.positions[ok, j]
        s = src[ok, b] - src[ok, a]
        cos = np.sum(d * s, axis=1) / np.linalg.norm(d, axis=1) / np.linalg.norm(s, axis=1)
        worst[KINECT20.joints[a] + "->" + KINECT20.joints[b]] = np.degrees(np.arccos(np.clip(cos, -1, 1))).max()
    return worst


def bone_lengths(plan, motion):
    """(T, B) lengths of every bone below the armature's top joint."""
    kids = np.flatnonzero(plan.parents >= 0)
    return np.linalg.norm(motion.positions[:, kids] - motion.positions[:, plan.parents[kids]], axis=2)


@pytest.mark.parametrize("name", HUMANOIDS)
def test_a_bvh_walk_keeps_bone_lengths_and_follows_every_bone_direction(rigged, walk, name):
    avatar, bonemap, plan = rigged[name]
    motion = retarget(plan, walk.positions, walk.tracked)
    assert np.isfinite(motion.world).all() and np.isfinite(motion.local).all()
    lengths = bone_lengths(plan, motion)
    assert np.abs(lengths - lengths[0]).max() < 1e-6
    worst = bone_directions_error(plan, bonemap, motion, walk.positions, walk.tracked)
    assert len(worst) >= 10                  # spine, neck, arms, legs (hands/feet where both have them)
    assert all(w < 1.0 for w in worst.values()), worst
    # the locals rebuild the worlds through the glTF hierarchy (what a player computes)
    j = int(np.flatnonzero(plan.real_parents >= 0)[-1])
    rebuilt = motion.world[:, plan.real_parents[j]] @ plan.fixed_parent[j] @ motion.local[:, j]
    np.testing.assert_allclose(rebuilt, motion.world[:, j], atol=1e-9 * np.ptp(avatar.bind_positions))


@pytest.mark.parametrize("name", HUMANOIDS)
def test_the_avatars_own_bind_skeleton_as_input_gives_back_the_bind_pose(rigged, name):
    avatar, bonemap, plan = rigged[name]
    p = avatar.bind_positions
    frame = np.full((20, 3), np.nan)
    for kj, j in bonemap.joints.items():
        frame[K(kj)] = p[j] @ plan.align          # into Kinetre's frame (facing +Z)
    frames = np.stack([frame, frame + [0.3, 0.0, -0.2]])  # second frame: the same, moved
    motion = retarget(plan, frames, np.isfinite(frames).all(axis=2))
    np.testing.assert_allclose(motion.rotations, np.broadcast_to(np.eye(3), motion.rotations.shape), atol=1e-9)
    np.testing.assert_allclose(motion.world[0], avatar.bind_world, atol=1e-9 * np.ptp(p))
    # the root travels by the source's displacement (same size: leg ratio 1), turned to the avatar's facing
    moved = motion.positions[1] - motion.positions[0]
    np.testing.assert_allclose(moved, np.broadcast_to(plan.align @ [0.3, 0.0, -0.2], moved.shape), atol=1e-9)


def test_root_travel_is_scaled_by_the_leg_lengths(rigged, walk):
    avatar, bonemap, plan = rigged["RiggedFigure"]
    small = retarget(plan, walk.positions, walk.tracked)
    big = retarget(plan, 2.0 * walk.positions, walk.tracked)     # a person twice as tall travels twice as far
    travel = lambda m: m.positions[:, plan.root] - m.positions[0, plan.root]
    np.testing.assert_allclose(travel(big), travel(small), atol=1e-9)
    np.testing.assert_allclose(big.rotations, small.rotations, atol=1e-9)
    # and the avatar travels (leg ratio) x the walker's distance
    walked = np.linalg.norm(walk.positions[-1, K("HipCenter")] - walk.positions[0, K("HipCenter")])
    legs = [np.linalg.norm(walk.positions[0, K(f"Hip{s}")] - walk.positions[0, K(f"Knee{s}")]) +
            np.linalg.norm(walk.positions[0, K(f"Knee{s}")] - walk.positions[0, K(f"Ankle{s}")]) for s in ("Left", "Right")]
    ratio = plan.leg_length / np.mean(legs)
    assert np.linalg.norm(travel(small)[-1]) == pytest.approx(ratio * walked, rel=0.02)


@pytest.mark.parametrize("name", HUMANOIDS)
def test_tracking_loss_holds_the_last_rotation_and_never_makes_nan(rigged, walk, name):
    avatar, bonemap, plan = rigged[name]
    rng = np.random.default_rng(3)
    pos, tracked = walk.positions.copy(), walk.tracked.copy()
    lost = rng.random(tracked.shape) < 0.2
    lost[10:14] = True                                     # everything lost for four frames
    lost[0] = False
    pos[lost] = np.nan
    tracked[lost] = False
    motion = retarget(plan, pos, tracked)
    assert np.isfinite(motion.world).all() and np.isfinite(motion.local).all()
    # a fully lost frame keeps every joint's local rotation and the root's place
    np.testing.assert_allclose(motion.local[10:14], np.broadcast_to(motion.local[9], motion.local[10:14].shape),
                               atol=1e-12)
    # an arm bone whose elbow is lost keeps its local rotation from the frame before
    upper = bonemap.joints["ShoulderLeft"]
    frames = [t for t in range(1, len(pos)) if not tracked[t, K("ElbowLeft")] and not 10 <= t < 14]
    assert frames
    for t in frames:
        np.testing.assert_allclose(motion.local[t, upper, :3, :3], motion.local[t - 1, upper, :3, :3], atol=1e-9)
    lengths = bone_lengths(plan, motion)
    assert np.abs(lengths - lengths[0]).max() < 1e-6


def test_a_stream_frame_by_frame_equals_the_batch(rigged, walk):
    avatar, bonemap, plan = rigged["CesiumMan"]
    pos, tracked = walk.positions.copy(), walk.tracked.copy()
    tracked[5:9, K("WristRight")] = False
    batch = retarget(plan, pos, tracked, RetargetState(scale=1.0))
    state = RetargetState(scale=1.0)
    stream = [retarget(plan, pos[t:t + 1], tracked[t:t + 1], state).world[0] for t in range(len(pos))]
    np.testing.assert_allclose(np.stack(stream), batch.world, atol=1e-12)


def test_openni17_frames_reach_the_avatar_through_kinect20():
    rng = np.random.default_rng(0)
    frame = rng.normal(size=(2, 17, 3))
    pos, tracked = kinect_from_openni(frame, np.ones((2, 17), bool))
    np.testing.assert_allclose(pos[:, K("ElbowLeft")], frame[:, OPENNI17.index("LeftElbow")])
    np.testing.assert_allclose(pos[:, K("HipCenter")],
                               frame[:, [OPENNI17.index("LeftHip"), OPENNI17.index("RightHip")]].mean(axis=1))
    assert not tracked[:, K("HandLeft")].any() and tracked[:, K("KneeRight")].all()


def test_the_docs_avatar_example_runs(data_dir):
    import re
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / "docs" / "avatars.md").read_text()
    code = next(b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "kinetre.avatar" in b)
    code = code.replace('"CesiumMan.glb"', repr(str(data_dir / "avatars" / "CesiumMan.glb")))
    code = code.replace('"walk.bvh"', repr(str(data_dir / "bvh" / "mocapbank_test.bvh")))
    scope: dict = {}
    exec(compile(code, "docs/avatars.md", "exec"), scope)
    assert len(scope["vertices"]) == len(scope["take"]) and np.isfinite(scope["vertices"][-1][0]).all()
