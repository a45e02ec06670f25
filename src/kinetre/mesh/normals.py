"""Area-weighted vertex normals, shared by vertices that sit at the same position (UV-seam copies)."""
from __future__ import annotations

import numpy as np


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) float64 unit normals: the area-weighted sum of the incident face normals.

    Copies of one position (split at UV seams) get the same normal, so the two sides of a seam skin
    identically. A vertex whose faces cancel (or with no faces) gets +Y rather than NaN.
    """
    _, weld = np.unique(vertices, axis=0, return_inverse=True)
    weld = weld.reshape(-1)
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2 * area
    acc = np.zeros((weld.max() + 1, 3))
    for c in range(3):
        np.add.at(acc, weld[faces[:, c]], face_n)
    n = acc[weld]
    length = np.linalg.norm(n, axis=1)
    ok = length > 1e-300
    n[ok] /= length[ok, None]
    n[~ok] = (0.0, 1.0, 0.0)
    return n
