"""Face fixtures: MediaPipe landmarks of the two shared photos (tracked once) and a panned face video."""
from __future__ import annotations

import shutil
import subprocess

import cv2
import pytest

from kinetre.face.landmarks import FaceTracker

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


def pan_video(source, target, seconds: float = 1.0) -> None:
    """The portrait panned sideways and rolled ±14° over `seconds` at 30 fps, 320x240 (y4m or mp4)."""
    assert shutil.which("ffmpeg"), "ffmpeg is needed (make setup installs it)"
    motion = ("scale=-2:520,pad=560:520:(ow-iw)/2:0,rotate='0.25*sin(2*PI*t/{s})':fillcolor=black,"
              "crop=320:240:120+40*sin(2*PI*t/{s}):30,format=yuv420p").format(s=seconds)
    codec = ["-f", "yuv4mpegpipe"] if str(target).endswith(".y4m") else ["-c:v", "libx264"]
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-loop", "1", "-i", str(source), "-t", str(seconds),
                    "-r", "30", "-vf", motion, *codec, str(target)], check=True, timeout=120)


@pytest.fixture(scope="session")
def face_video(data_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("face") / "pan.mp4"
    pan_video(data_dir / "images" / "face" / "face_frontal_portrait.jpg", path)
    return path
