"""Face landmarks: MediaPipe's FaceLandmarker on images and video, and landmark files (the annotation tool's).

The tracker is the Tasks FaceLandmarker of mediapipe 0.10.14 with the studio page's `face_landmarker.task`
(`kinetre.motion.landmarkers`, fully offline): IMAGE mode for photos, VIDEO mode for a video's frames. Of
its 478 landmarks the first 468 are Face Mesh's, on the canonical face mesh's vertices (the template); the
10 iris points after them are dropped, since the template has no vertex for them. Landmarks are returned in
pixels, (x · width, y · height, z · width), with MediaPipe's relative depth z on the scale of x. Each
tracked face also carries FaceLandmarker's 52 blendshapes (`kinetre.skeleton.mediapipe.BLENDSHAPES`).

A landmark file is JSON written by the studio's /annotate page (or `write_landmarks`):

    {"format": "kinetre-face-landmarks", "version": 1, "image": "photo.jpg", "width": W, "height": H,
     "landmarks": [[x, y], ...468], "mirrored": [[x, y], ...468]}

`mirrored` is the same annotation for the left/right flipped image: x ↦ W − x with the template's
left/right vertex permutation, so landmark i still means template vertex i (the paper's index-invariant
flip). Pixels, y down.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BadFaceError
from ..motion.landmarkers import Landmarkers
from .template import load_template

FORMAT = "kinetre-face-landmarks"


def mirrored(landmarks: np.ndarray, width: float) -> np.ndarray:
    """The landmarks of the left/right flipped image, still indexed by template vertex."""
    out = np.asarray(landmarks, dtype=float)[load_template().mirror].copy()
    out[:, 0] = width - out[:, 0]
    return out


def write_landmarks(path, landmarks: np.ndarray, width: int, height: int, image: str = "") -> None:
    """Save 2D landmarks (n, 2+) and their mirrored copy as a landmark file."""
    xy = np.asarray(landmarks, dtype=float)[:, :2]
    doc = {"format": FORMAT, "version": 1, "image": image, "width": int(width), "height": int(height),
           "landmarks": np.round(xy, 3).tolist(), "mirrored": np.round(mirrored(xy, width), 3).tolist()}
    Path(path).write_text(json.dumps(doc) + "\n", encoding="utf-8")


def read_landmarks(path, *, flipped: bool = False) -> tuple[np.ndarray, int, int]:
    """(landmarks (468, 2) pixels, width, height) from a landmark file; `flipped` reads the mirrored copy."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise BadFaceError(f"{path}: no such landmark file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise BadFaceError(f"{path}: not a landmark file ({e})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise BadFaceError(f"{path}: not a landmark file (format is not {FORMAT!r})")
    key = "mirrored" if flipped else "landmarks"
    n = load_template().size
    try:
        points = np.asarray(doc[key], dtype=float)
        width, height = int(doc["width"]), int(doc["height"])
    except (KeyError, TypeError, ValueError) as e:
        raise BadFaceError(f"{path}: landmark file lacks a valid {e} entry") from None
    if points.shape != (n, 2) or not np.isfinite(points).all():
        raise BadFaceError(f"{path}: {key!r} must be {n} finite [x, y] pairs, got shape {points.shape}")
    if width <= 0 or height <= 0:
        raise BadFaceError(f"{path}: width and height must be positive")
    return points, width, height


@dataclass(frozen=True, eq=False)
class TrackedFace:
    """One tracked face: landmarks (468, 3) in pixels (x, y, z · width) and blendshapes (52,) weights in
    [0, 1], named `kinetre.skeleton.mediapipe.BLENDSHAPES`."""

    landmarks: np.ndarray
    blendshapes: np.ndarray


class FaceTracker:
    """The most prominent face in photos (`static_image=True`: IMAGE mode) or in the frames of one video
    (VIDEO mode, which follows the face from frame to frame).

    Raises BadModelError when `face_landmarker.task` is missing or corrupted, BadMotionError without
    MediaPipe.
    """

    def __init__(self, static_image: bool = False):
        self._marks = Landmarkers(people=1, hands=False, face=True, video=not static_image, tiles=False,
                                  bodies=False)
        self._last_ms = -1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        self._marks.close()

    def face(self, bgr: np.ndarray, t: float | None = None) -> TrackedFace | None:
        """The face in a BGR uint8 image, or None when none is found. `t` is the frame's time in seconds
        (video; default: 1/30 s after the previous frame)."""
        import cv2
        ms = self._last_ms + 33 if t is None else int(round(1000 * t))
        ms = max(ms, self._last_ms + 1)           # VIDEO mode wants strictly increasing times
        self._last_ms = ms
        h, w = bgr.shape[:2]
        _, _, faces = self._marks.detect(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), ms)
        if not faces:
            return None
        n = load_template().size
        found = faces[0]
        landmarks = np.c_[found.image[:n] * [w, h], found.depth[:n] * w]
        return TrackedFace(landmarks, found.blendshapes)

    def track(self, bgr: np.ndarray, t: float | None = None) -> np.ndarray | None:
        """(468, 3) landmarks in pixels for a BGR uint8 image, or None when no face is found."""
        found = self.face(bgr, t)
        return None if found is None else found.landmarks
