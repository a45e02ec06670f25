"""Algorithm 2: a 3D face per frame from 468 landmarks, on the template's topology.

1. texture coordinates c_i = (x_i / width, y_i / height) — the paper's (x/w, 1 − y/h) with glTF's v-down;
2. the landmarks' pose T = (s, R, t) by weighted similarity alignment to the frontal template (align.py);
3. the aligned shape with depth from the template: vertex i keeps the template's depth z_i and takes the
   x', y' that T projects exactly onto landmark i,  [x', y'] = R₂⁻¹ ((χ_i − t)_xy / s − R[:2, 2] z_i)
   (R₂ the top-left 2×2 of R; for a pure roll this is the paper's 2D alignment);
4. scale: dividing by s expresses the aligned shape in template units (the paper's s_model / s_asm; one
   isotropic factor, so that a face's own width-to-height proportions survive);
5. translate so that the chin vertex sits at the anchor (an avatar's neck: position and orientation);
   with `turn` the face also takes the head's tracked rotation about the chin *(ours: a face on its own,
   without a body to turn it, then follows the head; the paper's face stays frontal on the avatar)*.
Caricature morphs (caricature.py) are added in the template frame between steps 4 and 5.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import BadFaceError
from .align import Similarity, align
from .template import FaceTemplate, load_template

CM = 0.01  # template centimetres → metres


@dataclass(frozen=True)
class Anchor:
    """Where the chin goes: a point and an orientation (e.g. an avatar's neck joint), per frame.

    The default places the face where the template itself sits (template chin, in metres, facing +z)."""

    position: np.ndarray = field(default_factory=lambda: load_template().vertices[load_template().chin] * CM)
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))


@dataclass(frozen=True)
class FaceFrame:
    """One reconstructed face: vertices (n, 3) in metres, uvs (n, 2), the head pose, the face-frame shape
    (n, 3) in template cm, the anchor that placed it and the head turn applied about the chin (3, 3)."""

    vertices: np.ndarray
    uvs: np.ndarray
    pose: Similarity
    face: np.ndarray
    anchor: Anchor
    turn: np.ndarray

    def project(self, vertices: np.ndarray | None = None) -> np.ndarray:
        """Image pixels (n, 2) of `vertices` (default: this frame's), seen through the head pose."""
        v = self.vertices if vertices is None else vertices
        t = load_template()
        local = (v - self.anchor.position) @ self.anchor.rotation @ self.turn / CM + self.face[t.chin]
        p = self.pose.apply(local)
        return np.c_[p[:, 0], -p[:, 1]]


def camera_points(landmarks: np.ndarray) -> np.ndarray:
    """Image landmarks (x right, y down, z towards the scene; pixels) → the y-up, z-to-camera frame."""
    flip = np.array([1.0, -1.0, -1.0])[: landmarks.shape[1]]
    return landmarks * flip


def reconstruct(landmarks: np.ndarray, width: int, height: int, *, anchor: Anchor | None = None,
                morphs: np.ndarray | None = None, weights: np.ndarray | None = None,
                turn: bool = False, template: FaceTemplate | None = None) -> FaceFrame:
    """Algorithm 2 on one frame.

    landmarks : (n, 2) pixels, or (n, 3) with MediaPipe's relative depth in pixels (z · width)
    width, height : the camera frame's size in pixels
    anchor : where the chin goes (default: the template's own place)
    morphs, weights : caricature displacements (k, n, 3) in template cm and their weights (k,)
    turn : also rotate the face about the chin by the head's tracked rotation

    Raises BadFaceError for the wrong number of landmarks, non-finite values or a head turned so far
    (> ~80°) that the template's depth cannot be projected back.
    """
    template = template or load_template()
    anchor = anchor or Anchor()
    landmarks = np.asarray(landmarks, dtype=float)
    if landmarks.ndim != 2 or landmarks.shape != (template.size, landmarks.shape[1]) or landmarks.shape[1] not in (2, 3):
        raise BadFaceError(f"face landmarks: expected ({template.size}, 2 or 3), got {landmarks.shape}")
    if not np.isfinite(landmarks).all() or width <= 0 or height <= 0:
        raise BadFaceError("face landmarks: non-finite values or an empty image")
    uvs = landmarks[:, :2] / np.array([width, height], dtype=float)                       # step 1
    points = camera_points(landmarks)
    pose = align(points, template.vertices, template.weights)                              # step 2
    r2, tilt = pose.rotation[:2, :2], pose.rotation[:2, 2]
    if abs(np.linalg.det(r2)) < 0.15:
        raise BadFaceError("face landmarks: the head is turned too far from the camera to rebuild the face")
    z = template.vertices[:, 2]
    q = (points[:, :2] - pose.translation[:2]) / pose.scale - np.outer(z, tilt)              # steps 3-4
    face = np.c_[np.linalg.solve(r2, q.T).T, z]
    if morphs is not None and weights is not None and len(weights):
        face = face + np.tensordot(np.asarray(weights, dtype=float), morphs, axes=1)
    rotation = pose.rotation if turn else np.eye(3)
    vertices = anchor.position + CM * (face - face[template.chin]) @ (anchor.rotation @ rotation).T  # step 5
    return FaceFrame(vertices, uvs, pose, face, anchor, rotation)
