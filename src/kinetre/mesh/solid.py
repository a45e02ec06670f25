"""Points against a triangle surface: whether they lie inside it (the generalized winding number) and how far
they are from it. Exact at the triangles' own resolution, so a small part (a bolt, a thumb) gets as sure an
answer as a big one.
"""
from __future__ import annotations

import numpy as np

CHUNK = 1 << 21  # point-triangle pairs per step (a few tens of MB of temporaries)


def _chunks(points: int, triangles: int):
    step = max(1, CHUNK // max(points, 1))
    for start in range(0, triangles, step):
        yield slice(start, min(start + step, triangles))


def winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(P,) the generalized winding number of every point with respect to the triangles `faces` of
    `vertices`: the solid angle they subtend over 4π (Van Oosterom and Strackee's formula per triangle).
    About 1 inside a closed outward-wound surface and 0 outside; an open surface (a plate, a shell with a hole)
    gives the fraction it wraps round the point, so a threshold of 1/2 still tells inside from outside."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64).reshape(-1, 3)]
    total = np.zeros(len(points))
    for s in _chunks(len(points), len(tri)):
        a, b, c = (tri[None, s, k] - points[:, None] for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        num = np.einsum("pti,pti->pt", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("pti,pti->pt", a, b) * lc + np.einsum("pti,pti->pt", a, c) * lb
               + np.einsum("pti,pti->pt", b, c) * la)
        total += np.arctan2(num, den).sum(axis=1)
    return total / (2.0 * np.pi)


def _segment_distances(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    s = np.clip(np.einsum("pti,pti->pt", p - a, ab) / np.maximum(np.einsum("pti,pti->pt", ab, ab), 1e-300), 0, 1)
    return np.linalg.norm(p - a - s[..., None] * ab, axis=2)


def surface_distances(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(P,) the distance from every point to the nearest point of the triangles `faces` of `vertices` (inf
    with no triangles)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64).reshape(-1, 3)]
    best = np.full(len(points), np.inf)
    for s in _chunks(len(points), len(tri)):
        a, b, c = (np.broadcast_to(tri[None, s, k], (len(points), s.stop - s.start, 3)) for k in range(3))
        p = np.broadcast_to(points[:, None], a.shape)
        n = np.cross(b - a, c - a)
        nn = np.einsum("pti,pti->pt", n, n)
        # the foot of the perpendicular lies within the triangle when it is on the inner side of all three edges
        inner = np.ones(nn.shape, bool)
        for u, v in ((a, b), (b, c), (c, a)):
            inner &= np.einsum("pti,pti->pt", np.cross(v - u, p - u), n) >= 0.0
        plane = np.abs(np.einsum("pti,pti->pt", p - a, n)) / np.sqrt(np.maximum(nn, 1e-300))
        edges = np.minimum(np.minimum(_segment_distances(p, a, b), _segment_distances(p, b, c)),
                           _segment_distances(p, c, a))
        d = np.where(inner & (nn > 0.0), np.minimum(plane, edges), edges)
        best = np.minimum(best, d.min(axis=1))
    return best
