"""Frame-to-model tracking: agreement score, recovery from a perturbed guess, lost frames."""
from __future__ import annotations

import numpy as np
import pytest

from kinetre.scan.frames import Intrinsics
from kinetre.scan.fuse import TSDFVolume
from kinetre.scan.track import TrackingParams, agreement, track_frame


def _camera(k, depth):
    return Intrinsics(depth.shape[1], depth.shape[0], k[0, 0], k[1, 1], k[0, 2], k[1, 2])


def test_agreement_scores_alignment():
    camera = Intrinsics(40, 30, 30.0, 30.0, 19.5, 14.5)
    depth = np.full((30, 40), 1.0, np.float32)
    fitness, rmse = agreement(depth, depth, camera, np.eye(4), 0.03)
    assert fitness == 1.0 and rmse == 0.0
    moved = np.eye(4)
    moved[2, 3] = 0.1  # 10 cm along the view: nothing agrees
    assert agreement(depth, depth, camera, moved, 0.03)[0] == 0.0
    moved[2, 3] = 0.01
    fitness, rmse = agreement(depth, depth, camera, moved, 0.03)
    assert fitness > 0.9 and abs(rmse - 0.01) < 1e-6


@pytest.mark.slow
def test_tracking_recovers_the_pose_and_rejects_a_foreign_frame(spot_scene):
    _, poses, k, colors, depths, _, _ = spot_scene
    camera = _camera(k, depths[0])
    relative = np.linalg.inv(poses[0]) @ poses
    volume = TSDFVolume(0.01)
    for i in (0, 1, 2):
        volume.integrate(colors[i], depths[i], camera, relative[i])
    previous = (colors[2], depths[2], relative[2])
    result = track_frame(volume, colors[3], depths[3], camera, previous)
    assert result.accepted and result.fitness > 0.8 and result.rmse < 0.01
    assert np.linalg.norm(result.pose[:3, 3] - relative[3][:3, 3]) < 0.005
    # a guess 2 cm along the view and 2 degrees off, no previous frame: ICP against the model converges (to
    # 1.1 cm since the truncation went from 6 to 3 voxels for thin parts, fuse.py; 0.8 cm before). (Sideways
    # along the floor the cow alone constrains ICP weakly; the odometry guess covers that direction.)
    guess = relative[3].copy()
    angle = np.radians(2.0)
    guess[:3, :3] = guess[:3, :3] @ np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0],
                                              [-np.sin(angle), 0, np.cos(angle)]])
    guess[:3, 3] += 0.02 * guess[:3, 2]
    result = track_frame(volume, colors[3], depths[3], camera, None, guesses=(guess,))
    assert result.accepted and np.linalg.norm(result.pose[:3, 3] - relative[3][:3, 3]) < 0.012
    # a frame of a flat wall 0.5 m away does not fit the model: lost, with the reason
    wall = np.full_like(depths[3], 0.5)
    lost = track_frame(volume, colors[3], wall, camera, previous)
    assert not lost.accepted and lost.reason.startswith("lost tracking")
    strict = track_frame(volume, colors[3], depths[3], camera, previous, TrackingParams(min_fitness=0.999))
    assert not strict.accepted and "fitness" in strict.reason


def test_depth_pyramid_averages_surfaces_but_not_across_edges_or_holes():
    from kinetre.scan.track import _pyrdown_depth
    # a ramp: the symmetric 5x5 Gaussian of a linear function is its value at the centre pixel (2y, 2x)
    y, x = np.mgrid[0:24, 0:32]
    ramp = (1.0 + 0.002 * x + 0.001 * y).astype(np.float32)
    half = _pyrdown_depth(ramp, np.float32(0.14))
    assert half.shape == (12, 16)
    np.testing.assert_allclose(half[1:-1, 1:-1], ramp[2:-2:2, 2:-2:2], atol=1e-5)
    # a 1 m step between two surfaces stays a step (no pixel in between), and a pixel without depth stays empty
    step = np.where(x < 16, 1.0, 2.0).astype(np.float32)
    step[10, 10] = 0.0
    half = _pyrdown_depth(step, np.float32(0.14))
    assert set(np.unique(half)) == {0.0, 1.0, 2.0}
    assert half[5, 5] == 0.0 and np.count_nonzero(half == 0.0) == 1
    assert np.all(half[:, 8:] == 2.0) and np.all(half[:, :8][half[:, :8] > 0] == 1.0)
