"""MediaPipe capture on the shared person images and video, and the 33 -> Kinect-20 mapping.

(The mapping lives in kinetre/skeleton/mediapipe.py; it is tested here with the capture that uses it.)
"""
from __future__ import annotations

import csv
import json
import math

import cv2
import numpy as np
import pytest

import kinetre
from kinetre.errors import BadMotionError
from kinetre.motion.capture import PoseTracker, capture_image, capture_video
from kinetre.skeleton.mediapipe import (FLIP, KINECT_FROM_MEDIAPIPE, MEDIAPIPE33, kinect_from_mediapipe,
                                        root_translation)

J = kinetre.KINECT20.index
# MediaPipe indices of the 12 COCO limb keypoints (shoulders, elbows, wrists, hips, knees, ankles)
COCO12 = {"left_shoulder": 11, "right_shoulder": 12, "left_elbow": 13, "right_elbow": 14, "left_wrist": 15,
          "right_wrist": 16, "left_hip": 23, "right_hip": 24, "left_knee": 25, "right_knee": 26,
          "left_ankle": 27, "right_ankle": 28}


@pytest.fixture(scope="module")
def video_take(data_dir):
    return capture_video(data_dir / "video" / "pose_1.mp4")


@pytest.mark.slow
def test_video_is_tracked_at_its_frame_rate(video_take):
    assert len(video_take) == 120 and video_take.fps == pytest.approx(30.0)
    assert video_take.model is kinetre.KINECT20
    assert video_take.tracked.mean() > 0.9, f"tracked {video_take.tracked.mean():.2f} of joint-frames"


@pytest.mark.slow
def test_video_arms_and_legs_move(video_take):
    p = video_take.positions
    for joint, least in (("WristLeft", 0.4), ("WristRight", 0.4), ("ElbowLeft", 0.15), ("KneeLeft", 0.1),
                         ("KneeRight", 0.1), ("AnkleLeft", 0.05), ("AnkleRight", 0.05)):
        rel = p[:, J(joint)] - p[:, J("HipCenter")]
        travel = np.nanmax(np.linalg.norm(rel - np.nanmedian(rel, axis=0), axis=1))
        assert travel > least, f"{joint} moves {travel:.2f} m relative to the hips (want > {least})"
    # arms go above the head in this clip (frame 45 is the bundled 'arms up' still)
    assert np.nanmax(p[:, J("WristLeft"), 1] - p[:, J("Head"), 1]) > 0.1


@pytest.mark.slow
def test_video_skeleton_is_upright_and_in_front_of_the_camera(video_take):
    p = video_take.positions
    assert np.nanmedian(p[:, J("Head"), 1] - p[:, J("AnkleLeft"), 1]) > 1.0
    depth = -p[:, J("HipCenter"), 2]
    assert np.all((depth > 1.0) & (depth < 10.0)), f"hip depth {depth.min():.2f}..{depth.max():.2f} m"
    # the person faces the camera: their left shoulder is on +x
    assert np.nanmedian(p[:, J("ShoulderLeft"), 0] - p[:, J("ShoulderRight"), 0]) > 0.15
    # One-Euro keeps the hips steady: frame-to-frame hip jitter below 5 cm
    assert np.nanmedian(np.linalg.norm(np.diff(p[:, 0], axis=0), axis=1)) < 0.05


@pytest.mark.slow
def test_video_landmarks_match_the_movenet_reference(data_dir):
    ref = json.loads((data_dir / "video" / "pose_1.movenet_reference.json").read_text())
    cap = cv2.VideoCapture(str(data_dir / "video" / "pose_1.mp4"))
    errors = []
    with PoseTracker(static_image=True) as tracker:
        for k in range(120):
            ok, bgr = cap.read()
            if k % 30:
                continue
            world, image, vis = tracker.landmarks(bgr)
            h, w = bgr.shape[:2]
            for name, m in COCO12.items():
                errors.append(math.dist((image[m, 0] * w, image[m, 1] * h), (ref[k][name]["x"], ref[k][name]["y"])))
    cap.release()
    med = float(np.median(errors))
    assert med < 0.03 * 576, f"median keypoint distance to MoveNet {med:.1f} px"


@pytest.mark.parametrize("row,name", [(0, "standing_woman.png"), (1, "standing_man_arms_crossed.jpeg")])
def test_image_landmarks_match_the_truth(data_dir, row, name):
    with open(data_dir / "images" / "pose" / "pose_landmark_truth.csv") as f:
        truth = list(csv.DictReader(f))[row]
    bgr = cv2.imread(str(data_dir / "images" / "pose" / name))
    with PoseTracker(static_image=True) as tracker:
        _, image, _ = tracker.landmarks(bgr)
    h, w = bgr.shape[:2]
    err = [math.dist((image[m, 0] * w, image[m, 1] * h), (float(truth[f"{n}_x"]), float(truth[f"{n}_y"])))
           for n, m in COCO12.items()]
    assert np.median(err) < 0.04 * h, f"{name}: median error {np.median(err):.1f} px of {h}"


@pytest.mark.slow
def test_photo_poses(data_dir):
    d = data_dir / "images" / "pose"
    warrior = capture_image(d / "warrior_arms_out.jpg").positions
    span = warrior[J("WristLeft"), 0] - warrior[J("WristRight"), 0]
    assert span > 1.0, f"arms out: wrists {span:.2f} m apart"
    assert abs(warrior[J("WristLeft"), 1] - warrior[J("ShoulderLeft"), 1]) < 0.2
    up = capture_image(d / "jumping_arms_up_pose1_frame045.jpg").positions
    assert min(up[J("WristLeft"), 1], up[J("WristRight"), 1]) > up[J("Head"), 1]
    crossed = capture_image(d / "standing_man_arms_crossed.jpeg")
    p = crossed.positions
    assert max(p[J("WristLeft"), 1], p[J("WristRight"), 1]) < p[J("ShoulderCenter"), 1]
    assert abs(p[J("WristLeft"), 0] - p[J("WristRight"), 0]) < 0.25  # hands near the body's middle
    assert 1.2 < crossed.height < 2.1


def test_mapping_rows():
    assert KINECT_FROM_MEDIAPIPE.shape == (20, 33) and len(MEDIAPIPE33) == 33
    np.testing.assert_allclose(KINECT_FROM_MEDIAPIPE.sum(axis=1), 1.0)
    world = np.random.default_rng(0).normal(size=(33, 3))
    pos, tracked = kinect_from_mediapipe(world, np.ones(33))
    np.testing.assert_allclose(pos[J("HipCenter")], 0.5 * (world[23] + world[24]))
    np.testing.assert_allclose(pos[J("HandRight")], 0.5 * (world[18] + world[20]))
    hc, sc = pos[J("HipCenter")], pos[J("ShoulderCenter")]
    np.testing.assert_allclose(pos[J("Spine")], hc + 0.25 * (sc - hc))
    vis = np.ones(33)
    vis[19] = 0.3  # left index finger hidden: the left hand is not tracked, the wrist is
    _, tracked = kinect_from_mediapipe(world, vis)
    assert not tracked[J("HandLeft")] and tracked[J("WristLeft")] and tracked.sum() == 19
    assert np.linalg.det(FLIP) == pytest.approx(1.0)  # a rotation: no mirrored skeleton


def test_root_translation_recovers_a_known_placement():
    rng = np.random.default_rng(3)
    world = rng.normal(scale=0.3, size=(33, 3))
    t_true = np.array([0.4, -0.2, 3.5])
    w, h, fov = 640, 480, 60.0
    f = 0.5 * w / math.tan(math.radians(fov) / 2)
    cam = world + t_true
    image = np.stack([cam[:, 0] / cam[:, 2] * f / w + 0.5, cam[:, 1] / cam[:, 2] * f / h + 0.5], axis=1)
    t = root_translation(world, image, np.ones(33, bool), w, h, fov)
    np.testing.assert_allclose(t, t_true, atol=1e-9)
    assert root_translation(world, image, np.arange(33) < 3, w, h, fov) is None


@pytest.mark.slow
def test_no_person_and_not_a_video(tmp_path):
    path = tmp_path / "empty_room.mp4"
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 10, (160, 120))
    for i in range(6):
        out.write(np.full((120, 160, 3), 30 * i, np.uint8))
    out.release()
    with pytest.raises(BadMotionError, match=r"empty_room.mp4: no person found in any of the 6 frames"):
        capture_video(path)
    junk = tmp_path / "junk.mp4"
    junk.write_text("not a video")
    with pytest.raises(BadMotionError, match="junk.mp4: cannot open"):
        capture_video(junk)
    with pytest.raises(BadMotionError, match="no such file"):
        capture_video(tmp_path / "missing.mp4")


def test_live_loop_calls_back_per_frame(data_dir):
    from kinetre.motion.capture import capture_camera
    got = []
    n = capture_camera(str(data_dir / "video" / "pose_1.mp4"), lambda sk, t, people: got.append((sk, t)),
                       max_frames=5)
    assert n == 5 and len(got) == 5
    assert all(t2 > t1 for (_, t1), (_, t2) in zip(got, got[1:]))
    assert all(sk.tracked.sum() >= 18 for sk, _ in got)
    with pytest.raises(BadMotionError, match="camera 99: cannot open"):
        capture_camera(99, lambda sk, t, people: None, max_frames=1)
