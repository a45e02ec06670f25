"""Skeleton hierarchies and named joint subsets."""
import numpy as np
import pytest

import kinetre
from kinetre.errors import BadSkeletonError
from kinetre.skeleton.models import KINECT20, OPENNI17, Skeleton, SkeletonModel
from kinetre.skeleton.subsets import SUBSETS, subset_mask


def test_kinect20_has_twenty_joints_nineteen_bones():
    assert len(KINECT20.joints) == 20 and KINECT20.bones.shape == (19, 2)
    assert KINECT20.joints[0] == "HipCenter" and KINECT20.parents[0] == -1
    assert ("ElbowLeft", "WristLeft") in {(KINECT20.joints[a], KINECT20.joints[b]) for a, b in KINECT20.bones}


def test_openni17_rooted_at_torso():
    assert len(OPENNI17.joints) == 17 and OPENNI17.bones.shape == (16, 2)
    assert OPENNI17.joints[OPENNI17.parents.index(-1)] == "Torso"


def test_generic_model_validates_parents():
    with pytest.raises(BadSkeletonError, match="joint 'b' has parent 5"):
        SkeletonModel("tail", ("a", "b"), (-1, 5))


def test_skeleton_shape_checked_and_nan_untracked():
    with pytest.raises(BadSkeletonError, match=r"positions must be \(20, 3\), got \(19, 3\)"):
        Skeleton(KINECT20, np.zeros((19, 3)), np.ones(19, bool))
    pos = np.zeros((20, 3))
    pos[3] = np.nan
    s = Skeleton(KINECT20, pos, np.ones(20, bool))
    assert not s.tracked[3] and s.tracked.sum() == 19


@pytest.mark.parametrize("name, count", [("left arm", 4), ("arms", 8), ("legs", 8), ("upper body", 11),
                                         ("lower body", 9), ("spine", 4), ("whole body", 20)])
def test_subsets(name, count):
    assert subset_mask(KINECT20, name).sum() == count


def test_user_list_mixes_subsets_and_joints():
    mask = subset_mask(KINECT20, ["HipCenter", "right arm"])  # the Luxo lamp
    assert mask.sum() == 5 and mask[KINECT20.index("HipCenter")] and mask[KINECT20.index("HandRight")]


def test_openni_subsets_map_names():
    assert subset_mask(OPENNI17, "left arm").sum() == 3  # shoulder, elbow, wrist


def test_unknown_subset_is_a_clear_error():
    with pytest.raises(BadSkeletonError, match="unknown joint subset 'tail'"):
        subset_mask(KINECT20, "tail")


def test_every_named_subset_is_listed():
    assert set(kinetre.subset_names()) == set(SUBSETS)


def test_exact_joint_name_wins_over_subset_name():
    assert subset_mask(KINECT20, "Spine").sum() == 1
    assert subset_mask(KINECT20, "spine").sum() == 4
