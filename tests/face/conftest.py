"""Face fixtures: MediaPipe landmarks of the two shared photos (tracked once) and a panned face video."""
from __future__ import annotations

import cv2
import pytest

from kinetre.face.landmarks import FaceTracker

from face.fixtures_face import pan_video

PHOTOS = ("face_frontal_portrait.jpg", "face_business_person.png")


@pytest.fixture(scope="session")
def photos(data_dir):
    """{name: (bgr image, (468, 3) landmarks in pixels)} for the shared face photos."""
    out = {}
    with FaceTracker(static_image=True) as tracker:
        for name in PHOTOS:
            image = cv2.imread(str(data_dir / "images" / "face" / name))
            landmarks = tracker.track(image)
            assert landmarks is not None, f"MediaPipe found no face in {name}"
            out[name] = (image, landmarks)
    return out


@pytest.fixture(scope="session")
def face_video(data_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("face") / "pan.mp4"
    pan_video(data_dir / "images" / "face" / "face_frontal_portrait.jpg", path)
    return path
