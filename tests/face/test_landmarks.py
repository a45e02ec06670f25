"""Landmark files (the annotation tool's output) and the mirrored copy for a flipped image."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from kinetre.errors import BadFaceError
from kinetre.face.landmarks import FaceTracker, mirrored, read_landmarks, write_landmarks
from kinetre.face.reconstruct import reconstruct


def test_mirrored_copy_matches_the_tracker_on_the_flipped_photo(photos):
    image, lm = photos["face_business_person.png"]
    h, w = image.shape[:2]
    with FaceTracker(static_image=True) as tracker:
        flipped = tracker.track(cv2.flip(image, 1))
    predicted = mirrored(lm[:, :2], w)
    err = np.linalg.norm(predicted - flipped[:, :2], axis=1)
    # without the left/right permutation the two eyes would swap places: tens of pixels
    assert np.median(err) < 4.0 and err.max() < 20.0
    unpermuted = np.c_[w - lm[:, 0], lm[:, 1]]
    assert np.median(np.linalg.norm(unpermuted - flipped[:, :2], axis=1)) > 3 * np.median(err)


def test_landmark_file_round_trip_rebuilds_the_same_face(photos, tmp_path):
    image, lm = photos["face_frontal_portrait.jpg"]
    h, w = image.shape[:2]
    path = tmp_path / "portrait.landmarks.json"
    write_landmarks(path, lm, w, h, image="portrait.jpg")
    back, bw, bh = read_landmarks(path)
    assert (bw, bh) == (w, h) and np.abs(back - lm[:, :2]).max() <= 5e-4
    flip, _, _ = read_landmarks(path, flipped=True)
    assert np.allclose(flip, mirrored(back, w), atol=1e-3)
    # a face rebuilt from the 2D file projects onto it, like one from the tracker's 3D landmarks
    frame = reconstruct(back, w, h)
    assert np.abs(frame.project() - back).max() < 2.0
    # the flipped annotation rebuilds the mirror image of the face (vertex i ↔ its mirror partner)
    from kinetre.face.template import load_template
    t = load_template()
    a = reconstruct(back, w, h).face
    b = reconstruct(flip, w, h).face
    assert np.abs(b[t.mirror] * [-1, 1, 1] - a).max() < 0.3                       # cm


@pytest.mark.parametrize("content, match", [
    ("not json", "not a landmark file"),
    ('{"format": "other"}', "format"),
    ('{"format": "kinetre-face-landmarks", "width": 10, "height": 10, "landmarks": [[1, 2]]}', "468"),
    ('{"format": "kinetre-face-landmarks", "landmarks": []}', "width"),
])
def test_bad_landmark_files_name_the_problem(tmp_path, content, match):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(BadFaceError, match=match):
        read_landmarks(path)
    with pytest.raises(BadFaceError, match="no such"):
        read_landmarks(tmp_path / "missing.json")


def test_file_format_is_plain_json(photos, tmp_path):
    image, lm = photos["face_frontal_portrait.jpg"]
    path = tmp_path / "x.json"
    write_landmarks(path, lm, image.shape[1], image.shape[0])
    doc = json.loads(path.read_text())
    assert doc["format"] == "kinetre-face-landmarks" and len(doc["landmarks"]) == len(doc["mirrored"]) == 468
