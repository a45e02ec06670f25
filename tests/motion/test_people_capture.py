"""Capture of several people, hands and faces with MediaPipe's Tasks landmarkers, on the shared video and
images; bad input gives one clear error."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

import kinetre
from kinetre.errors import BadModelError, BadMotionError
from kinetre.motion import models
from kinetre.motion.capture import CaptureSettings, capture_video, photo_people
from kinetre.motion.landmarkers import Landmarkers
from kinetre.skeleton.mediapipe import BLENDSHAPES

pytestmark = pytest.mark.slow  # `make check` leaves these out: see docs/testing.md

J = kinetre.KINECT20.index
JAW = BLENDSHAPES.index("jawOpen")


@pytest.fixture(scope="module")
def two_people(data_dir):
    # every 6th of the 60 frames: 10 frames, 0.2 s apart
    return capture_video(data_dir / "video" / "two_people_pose_1_640x360.mp4", every=6)


def test_two_people_in_a_wide_frame_are_both_found_with_stable_ids(two_people):
    take = two_people
    assert len(take) == 10 and take.fps == pytest.approx(5.0)
    assert len(take.people) == 2, f"ids {take.people}"
    seen = take.crowd_tracked.any(axis=2)                   # (frames, people)
    assert seen.all(), f"person seen per frame: {seen.astype(int).tolist()}"
    # each id stays on its own side of the image: the one on the left is always on the left
    hips = take.crowd_positions[:, :, J("HipCenter"), 0]    # x, metres, +x the camera's right
    side = np.sign(hips)
    assert (side[:, 0] == side[0, 0]).all() and (side[:, 1] == side[0, 1]).all() and side[0, 0] != side[0, 1]
    assert np.abs(hips[:, 0] - hips[:, 1]).min() > 1.0     # two bodies, not one found twice
    for k in range(2):
        body = take.crowd_positions[:, k]
        # the dancer lifts a knee at times: the head's height over the lower ankle, at its tallest
        lowest = np.fmin(body[:, J("AnkleLeft"), 1], body[:, J("AnkleRight"), 1])
        height = np.nanmax(body[:, J("Head"), 1] - lowest)
        assert 1.2 < height < 2.2, f"person {take.people[k]}: head above ankle {height:.2f} m"


def test_the_whole_frame_alone_misses_the_small_people_the_tiles_find(data_dir):
    cap = cv2.VideoCapture(str(data_dir / "video" / "two_people_pose_1_640x360.mp4"))
    ok, bgr = cap.read()
    cap.release()
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    with Landmarkers(people=4, hands=False, face=False, video=False, tiles=False) as whole:
        alone = len(whole.detect(rgb)[0])
    with Landmarkers(people=4, hands=False, face=False, video=False) as tiled:
        bodies = tiled.detect(rgb)[0]
    assert alone < 2 and len(bodies) == 2
    xs = sorted(float(np.median(b.image[:, 0])) for b in bodies)
    assert xs[0] < 0.5 < xs[1]                              # one in each half of the frame


def test_hands_are_found_at_the_wrists_of_a_standing_woman(data_dir):
    people = photo_people(data_dir / "images" / "pose" / "standing_woman.png")
    assert len(people) == 1
    p = people[0]
    assert p.hands is not None and np.isfinite(p.hands).all(), "both hands found"
    for side, wrist in ((0, "WristLeft"), (1, "WristRight")):
        hand = p.hands[side]
        np.testing.assert_allclose(hand[0], p.skeleton.positions[J(wrist)], atol=1e-9)
        span = np.linalg.norm(hand[12] - hand[0])           # wrist to middle finger tip
        assert 0.08 < span < 0.30, f"hand {side}: {span:.3f} m"
        # her arms hang: the fingers point down from the wrist
        assert hand[12, 1] < hand[0, 1] - 0.05


def open_mouth(bgr: np.ndarray, face_image: np.ndarray, gap: float) -> np.ndarray:
    """The photo with the jaw dropped: everything below the lips moved down by `gap` times the lips-to-chin
    distance (tapering off below the chin and towards the cheeks), the opening dark."""
    h, w = bgr.shape[:2]
    p = face_image * [w, h]
    lips = 0.5 * (p[13] + p[14])                            # inner upper and lower lip
    chin, left, right = p[152], p[61], p[291]               # chin, mouth corners
    d = gap * np.linalg.norm(chin - lips)
    cx, half = 0.5 * (left[0] + right[0]), 0.5 * abs(right[0] - left[0])
    x = np.arange(w, dtype=np.float32)[None, :]
    y = np.arange(h, dtype=np.float32)[:, None]
    across = np.clip(1.5 - 1.5 * np.abs(x - cx) / (0.5 * np.ptp(p[:, 0])), 0, 1)
    end = chin[1] + 2 * d
    drop = np.where(y < lips[1], 0, np.where(y < lips[1] + d, y - lips[1], np.where(
        y < chin[1] + d, d, np.clip(d * (end - y) / (end - chin[1] - d), 0, d))))
    out = cv2.remap(bgr, np.broadcast_to(x, (h, w)).astype(np.float32),
                    np.ascontiguousarray((y - drop * across).astype(np.float32)), cv2.INTER_LINEAR)
    mask = np.zeros((h, w), np.uint8)
    cv2.ellipse(mask, (int(cx), int(lips[1] + d / 2)), (int(0.85 * half), int(d / 2)), 0, 0, 360, 255, -1)
    out[mask > 0] = (30, 20, 45)
    return out


def jaw(bgr) -> tuple[float, np.ndarray]:
    with Landmarkers(people=1, hands=False, video=False) as marks:
        faces = marks.detect(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))[2]
    assert len(faces) == 1
    return float(faces[0].blendshapes[JAW]), faces[0].image


def test_jaw_open_rises_as_the_mouth_opens(data_dir):
    # no photo or clip in the data shows an open mouth, so a real portrait's jaw is dropped by warping it
    portrait = cv2.imread(str(data_dir / "images" / "face" / "face_frontal_portrait.jpg"))
    closed, marks = jaw(portrait)
    opened = [jaw(open_mouth(portrait, marks, gap))[0] for gap in (0.2, 0.4, 0.6)]
    assert closed < opened[0] < opened[1] < opened[2], f"jawOpen closed {closed:.3f}, opening {opened}"
    assert opened[1] - closed > 0.2
    # blendshapes are recorded per person: the face belongs to the portrait's one person
    people = photo_people(data_dir / "images" / "face" / "face_frontal_portrait.jpg")
    assert len(people) == 1 and people[0].blendshapes[JAW] == pytest.approx(closed, abs=1e-6)


def test_bad_input_names_the_file(tmp_path, data_dir, monkeypatch):
    with pytest.raises(BadMotionError, match="missing.mp4: no such file"):
        capture_video(tmp_path / "missing.mp4")
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"\0" * 100)
    with pytest.raises(BadMotionError, match="junk.mp4: cannot open"):
        capture_video(junk)
    monkeypatch.setattr(models, "search_dirs", lambda: (tmp_path,))
    with pytest.raises(BadModelError, match=r"pose_landmarker_full.task: not found .*make models"):
        capture_video(data_dir / "video" / "pose_1.mp4", max_frames=1)
    with pytest.raises(kinetre.errors.BadSettingsError, match="people must be 1 to 4"):
        CaptureSettings(people=5)


def test_the_command_records_both_people_and_refuses_bad_input_in_one_line(tmp_path, data_dir, capsys,
                                                                           monkeypatch):
    from kinetre.cli import main
    from kinetre.motion.stream import read_stream
    clip = data_dir / "video" / "two_people_pose_1_640x360.mp4"
    out = tmp_path / "two.kinetre.jsonl"
    assert main(["capture", "--video", str(clip), "--every", "20", "--no-face", "-q", "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "3 frames at 1.5 fps" in said and "2 people (ids 0, 1)" in said
    take = read_stream(out)
    assert take.people == (0, 1) and take.crowd_tracked.any(axis=2).all() and take.blendshapes is None

    def refused(*argv):
        code = main([str(a) for a in argv])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1, err
        return err[0]
    assert "missing.mp4: no such file" in refused("capture", "--video", tmp_path / "missing.mp4", "-o", out)
    junk = tmp_path / "junk.mp4"
    junk.write_text("not a video")
    assert "junk.mp4: cannot open" in refused("capture", "--video", junk, "-o", out)
    assert "people must be 1 to 4" in refused("capture", "--video", clip, "--people", 0, "-o", out)
    # without the models the command fetches them on first use (saying so); with no index to reach, one error line
    monkeypatch.setattr(models, "search_dirs", lambda: (tmp_path,))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("PIP_INDEX_URL", "http://127.0.0.1:9/simple/")
    assert main(["capture", "--video", str(clip), "-o", str(out)]) == 2
    notice, error = capsys.readouterr().err.strip().splitlines()
    assert notice.startswith("kinetre: first use: fetching the MediaPipe models")
    assert error.startswith("kinetre: error: cannot reach") and "pose_landmarker_full.task" in error
