"""Area-weighted vertex normals, shared by vertices that sit at the same position (UV-seam copies)."""
from __future__ import annotations

import numpy as np
from ..jit import njit


@njit(cache=True, inline="always")
def edges_and_cross(vertices, a, b, c):
    """The edges u = b − a, v = c − a of a triangle and u × v (length = twice its area)."""
    ux = vertices[b, 0] - vertices[a, 0]
    uy = vertices[b, 1] - vertices[a, 1]
    uz = vertices[b, 2] - vertices[a, 2]
    vx = vertices[c, 0] - vertices[a, 0]
    vy = vertices[c, 1] - vertices[a, 1]
    vz = vertices[c, 2] - vertices[a, 2]
    return ux, uy, uz, vx, vy, vz, uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx


@njit(cache=True)
def _accumulate(vertices, faces, index, size):
    # Σ over incident faces of e1 × e2 (length = 2 × area), face by face and corner by corner, the order
    # np.bincount adds in; and the total area
    acc = np.zeros((size, 3))
    area2 = 0.0
    for f in range(faces.shape[0]):
        nx, ny, nz = edges_and_cross(vertices, faces[f, 0], faces[f, 1], faces[f, 2])[6:]
        area2 += np.sqrt(nx * nx + ny * ny + nz * nz)
        for k in range(3):
            i = index[faces[f, k]]
            acc[i, 0] += nx
            acc[i, 1] += ny
            acc[i, 2] += nz
    return acc, 0.5 * area2


@njit(cache=True)
def _unit(acc, index):
    n = np.empty((index.shape[0], 3))
    for v in range(index.shape[0]):
        x, y, z = acc[index[v], 0], acc[index[v], 1], acc[index[v], 2]
        length = np.sqrt(x * x + y * y + z * z)
        if length > 1e-300:
            n[v, 0], n[v, 1], n[v, 2] = x / length, y / length, z / length
        else:  # faces cancel (or none): a unit normal rather than NaN
            n[v, 0], n[v, 1], n[v, 2] = 0.0, 1.0, 0.0
    return n


def normals_and_area(vertices: np.ndarray, faces: np.ndarray, weld: bool = True) -> tuple[np.ndarray, float]:
    """(V, 3) float64 unit normals — the area-weighted sum of the incident face normals — and the surface area.

    With `weld`, copies of one position (split at UV seams) get the same normal, so the two sides
    of a seam skin identically; pass False when vertices are known to be unique (it saves a sort).
    A vertex whose faces cancel (or with no faces) gets +Y rather than NaN.
    """
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    if weld:
        _, index = np.unique(vertices, axis=0, return_inverse=True)
        index = index.reshape(-1).astype(np.int64)
    else:
        index = np.arange(len(vertices), dtype=np.int64)
    size = int(index.max()) + 1 if len(index) else 0
    acc, area = _accumulate(vertices, np.ascontiguousarray(faces), index, size)
    return _unit(acc, index), float(area)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray, weld: bool = True) -> np.ndarray:
    """(V, 3) float64 unit area-weighted vertex normals (see `normals_and_area`)."""
    return normals_and_area(vertices, faces, weld)[0]
