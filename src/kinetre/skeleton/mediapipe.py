"""MediaPipe Pose's 33 landmarks -> Kinect-20, and the root translation from the image.

MediaPipe gives two sets per frame: world landmarks (metres, hip-centred, camera axes: x right, y down,
z away from the camera) and image landmarks (x, y normalised to the image, z relative depth). The world
set has the body's shape but no place; the place (so jumps and walking show) comes from fitting a
translation that projects the world landmarks onto the image ones (`root_translation`).
"""
from __future__ import annotations

import json
import math
from importlib import resources
from types import MappingProxyType

import numpy as np

from .models import FINGER_JOINTS, HAND21, KINECT20

MEDIAPIPE33 = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye", "right_eye_outer",
    "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder", "right_shoulder", "left_elbow",
    "right_elbow", "left_wrist", "right_wrist", "left_pinky", "right_pinky", "left_index", "right_index",
    "left_thumb", "right_thumb", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle",
    "right_ankle", "left_heel", "right_heel", "left_foot_index", "right_foot_index",
)

# Per finger, the indices of the hand landmarks its bones follow (wrist first: the finger's first bone leaves
# the palm); the landmarks are `HAND21`'s joints.
FINGERS = {finger: tuple(HAND21.index(j) for j in chain) for finger, chain in FINGER_JOINTS.items()}
# FaceLandmarker's blendshapes in its output order ("_neutral", then the 51 ARKit face-tracking names) and
# the VRM presets they drive: one table in the package data, which the page bundles too.
BLENDSHAPE_TABLE = MappingProxyType(json.loads(
    resources.files("kinetre").joinpath("data", "blendshapes.json").read_text(encoding="utf-8")))
BLENDSHAPES = tuple(BLENDSHAPE_TABLE["names"])

# Kinect joint -> MediaPipe landmarks averaged; Spine is derived below.
_SOURCES = {
    "HipCenter": (23, 24), "ShoulderCenter": (11, 12), "Head": (7, 8),
    "ShoulderLeft": (11,), "ElbowLeft": (13,), "WristLeft": (15,), "HandLeft": (17, 19),
    "ShoulderRight": (12,), "ElbowRight": (14,), "WristRight": (16,), "HandRight": (18, 20),
    "HipLeft": (23,), "KneeLeft": (25,), "AnkleLeft": (27,), "FootLeft": (31,),
    "HipRight": (24,), "KneeRight": (26,), "AnkleRight": (28,), "FootRight": (32,),
}


def _weights() -> np.ndarray:
    w = np.zeros((len(KINECT20.joints), len(MEDIAPIPE33)))
    for joint, marks in _SOURCES.items():
        w[KINECT20.index(joint), list(marks)] = 1.0 / len(marks)
    hc, sc = w[KINECT20.index("HipCenter")], w[KINECT20.index("ShoulderCenter")]
    w[KINECT20.index("Spine")] = hc + 0.25 * (sc - hc)  # a quarter of the way up the torso
    return w


KINECT_FROM_MEDIAPIPE = _weights()  # (20, 33): Kinect positions = this @ landmark positions
# Camera axes (x right, y down, z away) -> Kinetre (+Y up, facing the camera along +Z): half a turn about X.
FLIP = np.diag([1.0, -1.0, -1.0])
VISIBLE = 0.5  # landmarks below this visibility are "not tracked"


def kinect_from_mediapipe(world: np.ndarray, visibility: np.ndarray,
                          threshold: float = VISIBLE) -> tuple[np.ndarray, np.ndarray]:
    """Map landmarks to Kinect-20 (camera axes kept).

    Parameters
    ----------
    world : (..., 33, 3) float64
        Landmark positions, metres.
    visibility : (..., 33) float64
        MediaPipe's visibility scores in [0, 1].

    Returns
    -------
    positions : (..., 20, 3) float64
    tracked : (..., 20) bool
        True where every landmark a joint is made from is visible (>= `threshold`).
    """
    world = np.asarray(world, dtype=np.float64)
    seen = np.asarray(visibility) >= threshold
    positions = np.einsum("km,...mc->...kc", KINECT_FROM_MEDIAPIPE, world)
    uses = KINECT_FROM_MEDIAPIPE != 0
    tracked = ~np.einsum("km,...m->...k", uses, ~seen).astype(bool)
    return positions, tracked & np.isfinite(positions).all(axis=-1)


def root_translation(world: np.ndarray, image: np.ndarray, visible: np.ndarray, width: int, height: int,
                     fov_degrees: float = 60.0) -> np.ndarray | None:
    """Camera-space translation T of the hip-centred world landmarks, so that world + T projects onto the
    image landmarks through a pinhole camera with horizontal field of view `fov_degrees`.

    For each visible landmark, u = f (X + Tx) / (Z + Tz) is linear in T:  f Tx - u Tz = u Z - f X
    (likewise for v), solved in least squares. The apparent size of the body fixes the depth Tz.

    Parameters
    ----------
    world : (33, 3) metres, camera axes; image : (33, 2) normalised [0, 1] image coordinates;
    visible : (33,) bool; width, height : image size in pixels.

    Returns
    -------
    (3,) float64 in camera axes (x right, y down, z away), or None with fewer than 4 visible landmarks
    or a solution behind the camera.
    """
    idx = np.flatnonzero(visible)
    if len(idx) < 4:
        return None
    f = 0.5 * width / math.tan(math.radians(fov_degrees) / 2)
    u = (image[idx, 0] - 0.5) * width
    v = (image[idx, 1] - 0.5) * height
    x, y, z = world[idx].T
    zeros, ones = np.zeros_like(u), np.ones_like(u)
    a = np.block([[f * ones[:, None], zeros[:, None], -u[:, None]],
                  [zeros[:, None], f * ones[:, None], -v[:, None]]])
    b = np.concatenate([u * z - f * x, v * z - f * y])
    t, *_ = np.linalg.lstsq(a, b, rcond=None)
    if not np.isfinite(t).all() or t[2] <= 0:
        return None
    return t
