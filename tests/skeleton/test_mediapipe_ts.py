"""The page's first conversion on the live path, web/src/capture/KinectMapper.ts (run under node), against its
Python twin skeleton/mediapipe.py: the same Kinect-20 joints from the same landmarks, the same tracked rule,
and a root placed where a pinhole camera saw the body."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from kinetre.skeleton.mediapipe import FLIP, VISIBLE, kinect_from_mediapipe, root_translation
from web_bundle import bundled

RUNNER = Path(__file__).resolve().parent / "node" / "kinect_mapper_ts.mjs"
FOCAL, STAGE_DISTANCE, ASPECT = 1.0, 2.5, 4 / 3  # KinectMapper's pinhole (image-width units) and stage


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    return bundled(tmp_path_factory.mktemp("ts"), "capture/KinectMapper.ts")


def marks(points: np.ndarray, visibility: np.ndarray) -> list[dict]:
    return [{"x": float(x), "y": float(y), "z": float(z), "visibility": float(v)}
            for (x, y, z), v in zip(points, visibility)]


def run(bundle, frames) -> list[dict]:
    fixture = {"aspect": ASPECT, "frames": [{"world": w, "image": i} for w, i in frames]}
    out = subprocess.run(["node", str(RUNNER), str(bundle)], input=json.dumps(fixture), capture_output=True,
                         text=True, timeout=120, check=True)
    return json.loads(out.stdout)


def seen(world: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(33, 3) image landmarks of hip-centred `world` (camera axes) moved by `t`, through KinectMapper's pinhole:
    x in image widths, y in image heights, both from the top-left corner."""
    cam = world + t
    return np.column_stack([0.5 + FOCAL * cam[:, 0] / cam[:, 2], 0.5 + FOCAL * ASPECT * cam[:, 1] / cam[:, 2],
                            np.zeros(len(cam))])


def test_the_page_maps_landmarks_to_the_joints_the_python_twin_does(bundle):
    rng = np.random.default_rng(7)
    frames, expected = [], []
    for k in range(12):
        world = rng.normal(0.0, 0.4, (33, 3))
        visibility = rng.uniform(0.0, 1.0, 33) if k % 3 else np.ones(33)
        visibility[[11, 12, 23, 24]] = np.maximum(visibility[[11, 12, 23, 24]], VISIBLE)  # a torso to measure
        image = seen(world, np.array([0.1 * k - 0.5, 0.2, 3.0]))
        frames.append((marks(world, visibility), marks(image, np.ones(33))))
        expected.append(kinect_from_mediapipe(world, visibility))
    out = run(bundle, frames)
    assert len(out) == len(frames)
    for got, (positions, tracked) in zip(out, expected):
        assert got["tracked"] == tracked.tolist()
        assert [p is not None for p in got["positions"]] == tracked.tolist()
        assert tracked[0]  # the hip centre: the page adds its root translation to every joint alike
        ts = np.array([p for p in got["positions"] if p is not None])
        py = (positions[tracked] - positions[0]) @ FLIP.T  # +Y up, +Z toward the camera
        np.testing.assert_allclose(ts - ts[0], py - py[0], atol=1e-9)


def test_the_root_is_where_the_camera_saw_the_body_and_the_feet_stand_on_the_floor(bundle):
    """A body whose torso faces the camera: its depth follows from the torso's apparent length exactly, its
    hips from where they are in the image, and the first full-body frame puts the lowest foot on y = 0."""
    world = np.zeros((33, 3))
    world[[11, 12]] = [[-0.18, -0.5, 0.0], [0.18, -0.5, 0.0]]  # shoulders (camera axes: +Y down)
    world[[23, 24]] = [[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0]]  # hips: the hip centre is the origin
    world[[27, 28]] = [[-0.1, 0.85, 0.0], [0.1, 0.8, 0.0]]  # ankles
    world[[31, 32]] = [[-0.1, 0.9, 0.05], [0.1, 0.88, 0.05]]  # foot tips: the left one is lowest
    visibility = np.ones(33)
    stand, step = np.array([0.3, 0.4, 3.2]), np.array([-0.5, -0.2, 0.6])  # then a step aside, up and back
    out = run(bundle, [(marks(world, visibility), marks(seen(world, t), visibility)) for t in (stand, stand + step)])
    first, second = (np.array(o["positions"], dtype=float) for o in out)
    np.testing.assert_allclose(first[0], [stand[0], first[0][1], STAGE_DISTANCE - stand[2]], atol=1e-9)
    assert min(first[15][1], first[19][1]) == pytest.approx(0.0, abs=1e-9)  # FootLeft on the floor
    np.testing.assert_allclose(second[0] - first[0], step @ FLIP.T, atol=1e-9)  # the floor stays put


def test_a_torso_leaning_toward_the_camera_stays_where_it_stands(bundle):
    """A body bowing toward the camera looks shorter in the image, and is as short seen from there in metres:
    its depth is unchanged. (Its torso's length in metres against its length in the image read it as a body
    twice as far away: the two people of a horse flung metres back for a frame.)"""
    upright = np.zeros((33, 3))
    upright[[11, 12]] = [[-0.18, -0.5, 0.0], [0.18, -0.5, 0.0]]
    upright[[23, 24]] = [[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0]]
    upright[[25, 26]] = [[-0.1, 0.42, 0.0], [0.1, 0.42, 0.0]]  # knees
    upright[[27, 28, 31, 32]] = [[-0.1, 0.85, 0.0], [0.1, 0.85, 0.0], [-0.1, 0.9, -0.05], [0.1, 0.9, -0.05]]
    bowed = upright.copy()
    bowed[[11, 12]] = [[-0.18, -0.25, -0.43], [0.18, -0.25, -0.43]]  # shoulders 60 degrees toward the camera
    visibility = np.ones(33)
    stand = np.array([0.4, 0.3, 8.0])  # small in the view, as the dancers of a two-person horse are
    out = run(bundle, [(marks(w, visibility), marks(seen(w, stand), visibility)) for w in (upright, bowed)])
    first, second = (np.array(o["positions"], dtype=float) for o in out)
    assert first[0][2] == pytest.approx(STAGE_DISTANCE - stand[2], abs=1e-9)
    np.testing.assert_allclose(second[0], first[0], atol=1e-9)


def test_the_page_places_the_root_where_the_python_twin_does(bundle):
    """Landmarks that no pinhole fits exactly (MediaPipe's image and world landmarks disagree by a few
    pixels and centimetres): the page's root is the least-squares translation `kinetre capture` finds."""
    rng = np.random.default_rng(11)
    width, height = 640, 480  # ASPECT
    fov = np.degrees(2 * np.arctan(0.5 / FOCAL))
    frames, roots = [], []
    for k in range(8):
        world = rng.normal(0.0, 0.4, (33, 3))
        world -= (world[23] + world[24]) / 2
        visibility = np.where(rng.uniform(size=33) < 0.2, 0.1, 0.9)
        visibility[[23, 24, 27, 28, 31, 32]] = 0.9  # the hip centre (the root) and the feet (the floor)
        image = seen(world, np.array([0.3 * k - 1.0, 0.1, 3.0 + k])) + rng.normal(0.0, 0.004, (33, 3))
        frames.append((marks(world, visibility), marks(image, np.ones(33))))
        roots.append(root_translation(world, image[:, :2], visibility >= VISIBLE, width, height, fov))
    out = run(bundle, frames)
    got = np.array([o["positions"][0] for o in out], dtype=float)
    want = np.array(roots) @ FLIP.T  # +Y up, +Z toward the camera
    np.testing.assert_allclose(got[:, [0, 2]] - [0, STAGE_DISTANCE], want[:, [0, 2]], atol=1e-9)
    np.testing.assert_allclose(np.diff(got[:, 1]), np.diff(want[:, 1]), atol=1e-9)  # the floor is the page's
