"""Shared fixtures: synthetic RGB-D renders of Spot on a floor (with ground truth) and the real Redwood frames."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

import scan_synthetic as synthetic  # noqa: E402

# 320x240 is the smallest size at which point-to-plane tracking of a cow on a floor stays millimetre accurate
# (at 160x120 the floor dominates and ICP slides); 12 frames over 60 degrees keep the test around 20 s.
WIDTH, HEIGHT, FRAMES, ARC = 320, 240, 12, 60.0


@pytest.fixture(scope="session")
def spot_scene():
    """(scene, poses (N, 4, 4), K (3, 3), colours, noisy depths, exact depths, object masks)."""
    scene = synthetic.spot_on_plane()
    poses = synthetic.orbit(FRAMES, arc_degrees=ARC)
    k = synthetic.camera_matrix(WIDTH, HEIGHT)
    colors, depths, exact, masks = synthetic.render_with_exact(scene, poses, k, WIDTH, HEIGHT, noise=True, seed=1)
    return scene, poses, k, colors, depths, exact, masks


@pytest.fixture(scope="session")
def spot_frames(spot_scene, tmp_path_factory) -> Path:
    """The synthetic sequence written as a Redwood folder with intrinsics.json."""
    _, _, k, colors, depths, _, _ = spot_scene
    return synthetic.write_redwood(tmp_path_factory.mktemp("spot") / "frames", colors, depths, k, WIDTH, HEIGHT)


@pytest.fixture(scope="session")
def spot_plane_scan(spot_frames, tmp_path_factory):
    """scan(..., segment="plane") of the synthetic sequence at 1 cm voxels."""
    from kinetre.scan.pipeline import scan
    out = tmp_path_factory.mktemp("spot_out") / "spot.ply"
    return scan(spot_frames, out, segment="plane", voxel=0.01, progress=False)


@pytest.fixture(scope="session")
def tiny_frames(tmp_path_factory) -> Path:
    """Three 160x120 frames of the synthetic scene: for CLI, zip and error tests that only need a valid input."""
    scene = synthetic.spot_on_plane()
    poses = synthetic.orbit(3, arc_degrees=6.0)
    k = synthetic.camera_matrix(160, 120)
    colors, depths, _ = synthetic.render(scene, poses, k, 160, 120, noise=True)
    return synthetic.write_redwood(tmp_path_factory.mktemp("tiny") / "frames", colors, depths, k, 160, 120)

