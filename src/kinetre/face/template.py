"""The frontal face template: MediaPipe's canonical face mesh (468 vertices, one per tracked landmark).

Loaded from `kinetre/data/face_template.json`, extracted from `face_landmarker.task` by `kinetre.face.assets`.
Frame: centimetres, +x the face's left (image right), +y up, +z out of the face towards the camera.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np


@dataclass(frozen=True)
class FaceTemplate:
    """vertices (n, 3) cm, uvs (n, 2) (v down), triangles (m, 3), weights (n,) of the rigid landmarks
    (MediaPipe's Procrustes basis: forehead, nose bridge, eye corners, cheekbones; 0 for the mobile
    lips, lids and jaw), mirror (n,) the left/right vertex permutation, chin the anchor vertex."""

    vertices: np.ndarray
    uvs: np.ndarray
    triangles: np.ndarray
    weights: np.ndarray
    mirror: np.ndarray
    chin: int
    nose_tip: int

    @property
    def size(self) -> int:
        return len(self.vertices)


@lru_cache(maxsize=1)
def load_template() -> FaceTemplate:
    """The shipped template (read once)."""
    raw = json.loads(resources.files("kinetre").joinpath("data", "face_template.json").read_text(encoding="utf-8"))
    arrays = {k: np.asarray(raw[k]) for k in ("vertices", "uvs", "procrustes_weights")}
    for a in arrays.values():
        a.setflags(write=False)
    triangles = np.asarray(raw["triangles"], dtype=np.int32)
    mirror = np.asarray(raw["mirror"], dtype=np.int64)
    triangles.setflags(write=False)
    mirror.setflags(write=False)
    return FaceTemplate(arrays["vertices"].astype(float), arrays["uvs"].astype(float), triangles,
                        arrays["procrustes_weights"].astype(float), mirror, int(raw["chin"]), int(raw["nose_tip"]))
