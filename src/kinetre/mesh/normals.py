"""Area-weighted vertex normals, shared by vertices that sit at the same position (UV-seam copies)."""
from __future__ import annotations

import numpy as np


def vertex_normals(vertices: np.ndarray, faces: np.ndarray, weld: bool = True) -> np.ndarray:
    """(V, 3) float64 unit normals: the area-weighted sum of the incident face normals.

    With `weld`, copies of one position (split at UV seams) get the same normal, so the two sides
    of a seam skin identically; pass False when vertices are known to be unique (it saves a sort).
    A vertex whose faces cancel (or with no faces) gets +Y rather than NaN.
    """
    if weld:
        _, index = np.unique(vertices, axis=0, return_inverse=True)
        index = index.reshape(-1)
    else:
        index = np.arange(len(vertices))
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2 * area
    corners = index[faces].reshape(-1)
    size = int(index.max()) + 1
    # bincount sums per vertex far faster than np.add.at
    acc = np.stack([np.bincount(corners, np.repeat(face_n[:, c], 3), minlength=size) for c in range(3)], axis=1)
    n = acc[index]
    length = np.linalg.norm(n, axis=1)
    ok = length > 1e-300
    n[ok] /= length[ok, None]
    n[~ok] = (0.0, 1.0, 0.0)
    return n
