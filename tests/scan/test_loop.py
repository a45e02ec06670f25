"""Loop closure candidates: views that parted and came back are matched, views that never parted are not."""
from __future__ import annotations

import numpy as np

from kinetre.scan.features import Features
from kinetre.scan.loop import loop_edges


def _turn(degrees: float) -> np.ndarray:
    """Camera-to-world pose 1 m from the origin, turned about +y by `degrees`, looking at the origin."""
    a = np.radians(degrees)
    rotation = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = rotation @ np.array([0.0, 0.0, -1.0])
    return pose


def test_loop_edges_only_between_views_that_came_back():
    rng = np.random.default_rng(0)
    poses = {i: _turn(10.0 * i) for i in range(37)}  # a full turn in 10-degree steps; frame 36 sees what 0 saw
    world = rng.uniform(-0.2, 0.2, (200, 3))  # a textured object at the centre, the same keypoints in every view
    descriptors = rng.integers(0, 256, (200, 32), dtype=np.uint8)
    features = {}
    for i, pose in poses.items():
        camera_points = (world - pose[:3, 3]) @ pose[:3, :3]
        features[i] = Features(descriptors, camera_points)
    refined = []

    def refine(a, b, guess):
        refined.append((a, b))
        return guess, np.eye(6)

    edges = loop_edges(poses, features, refine)
    pairs = {(e.source, e.target) for e in edges}
    # within 45 degrees and 3+ frames apart, (0, 3) and (0, 4) never parted (the camera turned 30 and 40 degrees
    # on); pairs across the wrap-around did (40 degrees or less apart, after turning more than 45 away)
    expected = {(a, b) for a in poses for b in poses
                if b - a >= 5 and min(10 * (b - a) % 360, 360 - 10 * (b - a) % 360) <= 45}
    assert pairs == expected and (0, 36) in pairs and (0, 31) not in pairs
    assert len(refined) == len(expected)
    for edge in edges:
        truth = np.linalg.inv(poses[edge.target]) @ poses[edge.source]
        np.testing.assert_allclose(edge.transform, truth, atol=1e-6)
        assert edge.loop
