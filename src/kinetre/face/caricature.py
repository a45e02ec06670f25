"""Caricatures: morph targets on the template's regions (the paper's "morphs applied in real time").

Each morph is a displacement field D (n, 3) in template centimetres; a face is  face + Σ_k α_k D_k, so at
weight 0 nothing moves, and the fields export unchanged as glTF morph targets. A region is a centre and a
radius on the template; its vertices move with the smooth falloff φ(d) = (1 − (d/r)²)² (C¹ at the rim, so
no crease where the region ends). At weight 1:

  eyes      each eye scaled 1.5× in x, y about its centre
  nose      the nose scaled 1.6× about the bridge root and pushed out 1.5 cm at the tip
  mouth     the lips widened 1.5× and thickened 1.3×
  jaw       the lower face widened up to 1.4× (most at the chin's height)
  forehead  the brows and above stretched 1.35× upwards from the eyes' height
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .template import FaceTemplate, load_template

NAMES = ("eyes", "nose", "mouth", "jaw", "forehead")

# MediaPipe Face Mesh landmark indices (the canonical mesh's vertex ids)
RIGHT_EYE = (33, 7, 163, 144, 145, 153, 154, 155, 133, 173, 157, 158, 159, 160, 161, 246)
LEFT_EYE = (263, 249, 390, 373, 374, 380, 381, 382, 362, 398, 384, 385, 386, 387, 388, 466)
LIPS = (61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291, 409, 270, 269, 267, 0, 37, 39, 40, 185)
NOSE_ROOT = 168

PRESETS = {
    "none": {},
    "big eyes": {"eyes": 1.0},
    "big nose": {"nose": 1.0, "eyes": -0.3},
    "grin": {"mouth": 1.0, "jaw": 0.3},
    "heavy jaw": {"jaw": 1.0, "forehead": -0.4},
    "egghead": {"forehead": 1.0, "jaw": -0.5, "eyes": 0.4},
}


def falloff(d: np.ndarray, radius: float) -> np.ndarray:
    """φ(d) = (1 − (d/r)²)² inside the radius, 0 outside."""
    x = np.clip(1.0 - (d / radius) ** 2, 0.0, None)
    return x * x


def _scaled(v: np.ndarray, centre: np.ndarray, factors, radius: float) -> np.ndarray:
    """Displacement scaling the region about `centre` by `factors` (per axis), faded by the falloff."""
    rel = v - centre
    phi = falloff(np.linalg.norm(rel, axis=1), radius)
    return phi[:, None] * rel * (np.asarray(factors, dtype=float) - 1.0)


@lru_cache(maxsize=1)
def _default_morphs() -> np.ndarray:
    return _build(load_template())


def morph_targets(template: FaceTemplate | None = None) -> np.ndarray:
    """(5, n, 3) displacements in template cm, in the order of NAMES (read-only for the shipped template)."""
    return _default_morphs() if template is None else _build(template)


def _build(t: FaceTemplate) -> np.ndarray:
    v = t.vertices
    out = np.zeros((len(NAMES), len(v), 3))
    for eye in (RIGHT_EYE, LEFT_EYE):
        c = v[list(eye)].mean(axis=0)
        r = 1.9 * np.linalg.norm(v[list(eye)] - c, axis=1).max()
        out[0] += _scaled(v, c, (1.5, 1.5, 1.0), r)
    root, tip = v[NOSE_ROOT], v[t.nose_tip]
    r = 1.25 * np.linalg.norm(tip - root)
    out[1] = _scaled(v, root, (1.6, 1.6, 1.6), r)
    out[1, :, 2] += 1.5 * falloff(np.linalg.norm(v - tip, axis=1), 0.6 * r)
    c = v[list(LIPS)].mean(axis=0)
    r = 1.6 * np.linalg.norm(v[list(LIPS)] - c, axis=1).max()
    out[2] = _scaled(v, c, (1.5, 1.3, 1.0), r)
    # jaw: widen about the midline, growing from the mouth's height (0) to the chin (1)
    y_mouth, y_chin = c[1], v[t.chin, 1]
    ramp = np.clip((y_mouth - v[:, 1]) / (y_mouth - y_chin), 0.0, 1.0)
    s = ramp * ramp * (3 - 2 * ramp)
    out[3, :, 0] = 0.4 * s * v[:, 0]
    # forehead: stretch upwards from the eyes' height, fading in over 2 cm (brows and above move)
    y_eyes = v[list(RIGHT_EYE + LEFT_EYE), 1].mean()
    lift = np.clip(v[:, 1] - y_eyes, 0.0, None)
    fade = np.clip(lift / 2.0, 0.0, 1.0)
    out[4, :, 1] = 0.35 * lift * fade * fade * (3 - 2 * fade)
    out.setflags(write=False)
    return out


def weights_from(values: dict[str, float]) -> np.ndarray:
    """Morph weights (5,) in NAMES order from {name: weight} (unknown names are an error)."""
    unknown = set(values) - set(NAMES)
    if unknown:
        raise ValueError(f"unknown caricature morph {sorted(unknown)[0]!r}; choose from {', '.join(NAMES)}")
    return np.array([float(values.get(n, 0.0)) for n in NAMES])
