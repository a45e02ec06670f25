"""BVH export: the written file gives back the take's joint positions when read again."""
from __future__ import annotations

import numpy as np
import pytest
from export.bvh_reader import read_bvh_positions
from export.takes import TPOSE, rigid_take, tracked_take
from kinetre.errors import ExportError
from kinetre.export.bvh import rotation_residuals, write_bvh
from kinetre.skeleton.models import KINECT20, OPENNI17, Skeleton, SkeletonModel

def max_error(path, take):
    read, _ = read_bvh_positions(path)
    worst = 0.0
    for j, name in enumerate(take[0].model.joints):
        truth = np.stack([s.positions[j] for s in take])
        ok = np.array([s.tracked[j] for s in take])
        worst = max(worst, float(np.linalg.norm(read[name][ok] - truth[ok], axis=1).max()))
    return worst, read


def test_tracked_take_round_trips_within_a_tenth_of_a_millimetre(tmp_path):
    take = tracked_take()
    write_bvh(tmp_path / "take.bvh", take, 30.0)
    err, read = max_error(tmp_path / "take.bvh", take)
    assert err < 1e-4
    assert all(np.isfinite(v).all() for v in read.values())      # lost joints are filled, not NaN
    text = (tmp_path / "take.bvh").read_text()
    assert "ROOT HipCenter" in text and "Frames: 30" in text and "Frame Time: 0.0333333333" in text
    # a lost hand sits at its rest distance from the wrist
    hand = read["HandLeft"][3] - read["WristLeft"][3]
    rest = np.array(TPOSE["HandLeft"]) - np.array(TPOSE["WristLeft"])
    assert np.linalg.norm(hand) == pytest.approx(np.linalg.norm(take[0].positions[7] - take[0].positions[6]), abs=1e-5)
    assert np.linalg.norm(hand) == pytest.approx(np.linalg.norm(rest), abs=0.03)


def test_rotation_only_layout_is_exact_for_a_rigid_skeleton(tmp_path):
    take = rigid_take()
    write_bvh(tmp_path / "rigid.bvh", take, 60.0, joint_positions=False)
    assert "CHANNELS 3 Zrotation Xrotation Yrotation" in (tmp_path / "rigid.bvh").read_text()
    err, _ = max_error(tmp_path / "rigid.bvh", take)
    assert err < 1e-4
    assert np.nanmax(rotation_residuals(take)) < 1e-6


def test_rotation_residual_of_tracked_data_is_reported(tmp_path):
    """Jittered bone lengths cannot be followed by rotations: the residual is of the jitter's size."""
    take = tracked_take()
    res = rotation_residuals(take)
    assert 0.005 < np.nanmedian(res) < 0.05
    write_bvh(tmp_path / "rot.bvh", take, 30.0, joint_positions=False)
    err, _ = max_error(tmp_path / "rot.bvh", take)
    assert err == pytest.approx(np.nanmax(res), rel=1e-3)


def test_other_hierarchies_are_written_in_their_own_joints(tmp_path):
    rest = np.array([[0, 1.0, 0], [0, 1.4, 0], [0, 1.6, 0], [-0.1, 1.4, 0], [-0.2, 1.4, 0], [-0.45, 1.4, 0],
                     [-0.7, 1.4, 0], [0.1, 1.4, 0], [0.2, 1.4, 0], [0.45, 1.4, 0], [0.7, 1.4, 0],
                     [-0.1, 0.95, 0], [-0.1, 0.5, 0], [-0.1, 0.05, 0], [0.1, 0.95, 0], [0.1, 0.5, 0],
                     [0.1, 0.05, 0]])
    take = rigid_take(10, 3, OPENNI17, rest)
    write_bvh(tmp_path / "openni.bvh", take, 30.0)
    err, read = max_error(tmp_path / "openni.bvh", take)
    assert err < 1e-4 and set(read) == set(OPENNI17.joints)


def test_bad_takes_raise_export_errors(tmp_path):
    take = rigid_take(3)
    with pytest.raises(ExportError, match=r"a\.bvh: the take has no frames"):
        write_bvh(tmp_path / "a.bvh", [], 30.0)
    with pytest.raises(ExportError, match="fps must be a positive number"):
        write_bvh(tmp_path / "a.bvh", take, -1.0)
    other = Skeleton(OPENNI17, np.zeros((17, 3)), np.ones(17, bool))
    with pytest.raises(ExportError, match="frame 1 has skeleton 'openni17'"):
        write_bvh(tmp_path / "a.bvh", [take[0], other], 30.0)
    lost = [Skeleton(KINECT20, np.full((20, 3), np.nan), np.zeros(20, bool))]
    with pytest.raises(ExportError, match="no frame of the take tracks any joint"):
        write_bvh(tmp_path / "a.bvh", lost, 30.0)
    two_roots = SkeletonModel("pair", ("a", "b"), (-1, -1))
    with pytest.raises(ExportError, match="one root joint"):
        write_bvh(tmp_path / "a.bvh", [Skeleton(two_roots, np.zeros((2, 3)), np.ones(2, bool))], 30.0)
