"""Every skeleton's constraint targets from one numba call on the rig's stacked arrays (`StackedAttachments`,
`stacked_targets`) equal each attachment's own `constraint_targets`; the allocation-free bone rotations equal
the frames they are defined by, built with numpy."""
import numpy as np
import pytest

import kinetre
from kinetre.motion.bvh import load_bvh
from kinetre.rotation import minimal_rotations as minimal_rotation
from kinetre.skeleton.attach import bone_rotations, constraint_targets
from kinetre.skeleton.models import Skeleton
from synthetic import capsule_body


@pytest.fixture(scope="module")
def two_models(data_dir):
    """The CMU walk as Kinect-20 and, 3 cm aside, in the file's own 31-joint hierarchy: two skeleton models
    driving one capsule body."""
    kinect = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    own = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh", as_kinect=False)
    a = [kinect.frame(i) for i in range(0, 120, 6)]
    b = [own.frame(i).transformed(translation=(0.03, 0.0, 0.0)) for i in range(0, 120, 6)]
    graph = kinetre.build_graph(capsule_body(a[0], radius=0.07), nodes=128, seed=0)
    return graph, a, b


def lose(frame: Skeleton, joints) -> Skeleton:
    """The frame with `joints` untracked, one of them at NaN (a tracker's lost joint)."""
    pos, tracked = frame.positions.copy(), frame.tracked.copy()
    tracked[list(joints)] = False
    pos[joints[0]] = np.nan
    return Skeleton(frame.model, pos, tracked)


@pytest.mark.slow
def test_stacked_targets_equal_each_attachments(two_models):
    graph, a, b = two_models
    rig = kinetre.attach(graph, [a[0], b[0]])
    assert all(att.bone_sample_count and att.joint_count for att in rig.attachments)
    assert rig.attachments[0].bind.model != rig.attachments[1].bind.model
    checked_lost = 0
    for i, (fa, fb) in enumerate(zip(a[1:], b[1:])):
        if i % 3 == 1:  # an elbow and a knee lost: their bones' samples drop out, their children turn alone
            fa, fb = lose(fa, [5, 13]), lose(fb, [3, 20])
        q, ok = rig.targets([fa, fb])
        parts = [constraint_targets(att, f) for att, f in zip(rig.attachments, (fa, fb))]
        want_q, want_ok = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        np.testing.assert_array_equal(ok, want_ok)
        np.testing.assert_allclose(q, want_q, rtol=0, atol=1e-14)
        checked_lost += int((~ok).sum())
        assert np.isfinite(q).all()
    assert checked_lost > 20  # the lost joints really dropped constraints


def reference_bone_rotations(bind: Skeleton, frame: Skeleton, reference: np.ndarray) -> np.ndarray:
    """`bone_rotations`' definition in numpy: the frame (u, w, u × w) of each bone and its twist reference,
    else the parent bone's rotation corrected by the minimal rotation, else the minimal rotation; a bone of
    zero length (the file's hierarchy has some) keeps its bind direction."""
    bones = frame.model.bones

    def unit(v):
        n = np.linalg.norm(v)
        return (v / n, True) if n > 1e-12 else (np.zeros(3), False)

    u0 = [unit(bind.positions[c] - bind.positions[p])[0] for p, c in bones]
    u1, ok = zip(*[unit(frame.positions[c] - frame.positions[p]) for p, c in bones])
    u1 = [u if k else u0[b] for b, (u, k) in enumerate(zip(u1, ok))]
    rot = minimal_rotation(np.array(u0), np.array(u1))
    own = np.zeros(len(bones), bool)
    for b, r in enumerate(reference):
        if r < 0 or not ok[b]:
            continue
        r0 = bind.positions[bones[r, 1]] - bind.positions[bones[r, 0]]
        r1 = frame.positions[bones[r, 1]] - frame.positions[bones[r, 0]]
        (w0, k0), (w1, k1) = unit(r0 - (r0 @ u0[b]) * u0[b]), unit(r1 - (r1 @ u1[b]) * u1[b])
        if k0 and k1:
            f0 = np.stack([u0[b], w0, np.cross(u0[b], w0)], axis=1)
            f1 = np.stack([u1[b], w1, np.cross(u1[b], w1)], axis=1)
            rot[b], own[b] = f1 @ f0.T, True
    parent = {c: i for i, (_, c) in enumerate(bones)}
    for b, (p, c) in enumerate(bones):
        if not own[b] and ok[b] and p in parent:
            pb = parent[p]
            rot[b] = minimal_rotation(rot[pb] @ u0[b], u1[b]) @ rot[pb]
    return rot


def test_bone_rotations_equal_their_numpy_definition(two_models):
    graph, a, b = two_models
    for frames in (a, b):
        rig = kinetre.attach(graph, frames[0])
        att = rig.attachments[0]
        assert (att.twist_reference >= 0).any() and (att.twist_reference < 0).any()
        for f in frames[1::4]:
            got = bone_rotations(att.bind, f, att.twist_reference)
            np.testing.assert_allclose(got, reference_bone_rotations(att.bind, f, att.twist_reference),
                                       rtol=0, atol=1e-13)
            np.testing.assert_allclose(got @ got.transpose(0, 2, 1), np.broadcast_to(np.eye(3), got.shape),
                                       atol=1e-12)
