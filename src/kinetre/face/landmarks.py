"""Face landmarks: MediaPipe Face Mesh on images and video, and landmark files (the annotation tool's).

MediaPipe (`mp.solutions.face_mesh.FaceMesh` of the 0.10.14 wheel, fully offline) gives 468 landmarks
in normalised image coordinates with a relative depth z (same scale as x); they are returned in pixels,
(x · width, y · height, z · width).

A landmark file is JSON written by the studio's /annotate page (or `write_landmarks`):

    {"format": "kinetre-face-landmarks", "version": 1, "image": "photo.jpg", "width": W, "height": H,
     "landmarks": [[x, y], ...468], "mirrored": [[x, y], ...468]}

`mirrored` is the same annotation for the left/right flipped image: x ↦ W − x with the template's
left/right vertex permutation, so landmark i still means template vertex i (the paper's index-invariant
flip). Pixels, y down.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import BadFaceError
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


class FaceTracker:
    """MediaPipe Face Mesh over images (`static_image=True`) or the frames of one video."""

    def __init__(self, static_image: bool = False):
        try:
            import mediapipe as mp
        except ImportError:
            raise BadFaceError("face tracking needs MediaPipe: pip install 'kinetre[capture]' "
                                 "(mediapipe==0.10.14)") from None
        self._mesh = mp.solutions.face_mesh.FaceMesh(static_image_mode=static_image, max_num_faces=1,
                                                     refine_landmarks=False, min_detection_confidence=0.5,
                                                     min_tracking_confidence=0.5)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._mesh.close()

    def track(self, bgr: np.ndarray) -> np.ndarray | None:
        """(468, 3) landmarks in pixels for a BGR uint8 image, or None when no face is found."""
        import cv2
        h, w = bgr.shape[:2]
        result = self._mesh.process(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        if not result.multi_face_landmarks:
            return None
        lm = result.multi_face_landmarks[0].landmark
        return np.array([[p.x * w, p.y * h, p.z * w] for p in lm[: load_template().size]])
