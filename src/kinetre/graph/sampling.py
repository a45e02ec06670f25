"""Orientation-aware Poisson-disk sampling by dart throwing (KinÊtre paper, Eq. 6).

Area-weighted random surface points are visited in random order; a point becomes a node when its
orientation-aware distance D (Eq. 6) to every accepted node is at least R. R = sqrt(A / N) for a
target count N, refined by bisection until the count is within N ± 10 %.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import BadGraphError
from ..jit import njit
from ..mesh.mesh import bounding_box
from ..mesh.normals import edges_and_cross
from .distance import distance_5d

@njit(cache=True)
def face_double_areas(vertices, faces):
    """(F,) float64: twice each triangle's area (|e1 × e2|), without (F, 3, 3) temporaries."""
    out = np.empty(faces.shape[0])
    for f in range(faces.shape[0]):
        nx, ny, nz = edges_and_cross(vertices, faces[f, 0], faces[f, 1], faces[f, 2])[6:]
        out[f] = np.sqrt(nx * nx + ny * ny + nz * nz)
    return out


def surface_points(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray, count: int,
                   rng: np.random.Generator, double_areas: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted random points on the triangles, with interpolated unit normals.

    Returns
    -------
    points : (count, 3) float64
    point_normals : (count, 3) float64
    """
    return _surface_samples(vertices, faces, normals, count, rng, double_areas)[:2]


def _surface_samples(vertices, faces, normals, count, rng, double_areas=None):
    """`surface_points` and the (count,) triangle each point lies on."""
    if double_areas is None:
        double_areas = face_double_areas(vertices, faces)
    cum = np.cumsum(double_areas)
    chosen = np.searchsorted(cum, rng.random(count) * cum[-1], side="right")
    chosen = np.minimum(chosen, len(faces) - 1)
    # uniform barycentric coordinates by the square-root trick
    r1 = np.sqrt(rng.random(count))
    r2 = rng.random(count)
    bary = np.stack([1.0 - r1, r1 * (1.0 - r2), r1 * r2], axis=1)
    f = faces[chosen]
    tri = vertices[f]
    points = np.einsum("ni,nij->nj", bary, tri)
    n = np.einsum("ni,nij->nj", bary, normals[f])
    length = np.linalg.norm(n, axis=1)
    flat = length < 1e-8  # normals cancel inside the triangle: use the face's own
    n[flat] = np.cross(tri[flat, 1] - tri[flat, 0], tri[flat, 2] - tri[flat, 0])
    n /= np.linalg.norm(n, axis=1)[:, None]
    return points, n, chosen


@njit(cache=True)
def _dart_throw(points, normals, radius, table_bits):
    m = points.shape[0]
    size = 1 << table_bits
    mask = size - 1
    head = np.full(size, -1, np.int64)
    nxt = np.full(m, -1, np.int64)
    accepted = np.empty(m, np.int64)
    count = 0
    inv = 1.0 / radius
    for c in range(m):
        px, py, pz = points[c, 0], points[c, 1], points[c, 2]
        nx, ny, nz = normals[c, 0], normals[c, 1], normals[c, 2]
        ci = int(np.floor(px * inv))
        cj = int(np.floor(py * inv))
        ck = int(np.floor(pz * inv))
        ok = True
        for di in range(-1, 2):
            if not ok:
                break
            for dj in range(-1, 2):
                if not ok:
                    break
                for dk in range(-1, 2):
                    h = (((ci + di) * 73856093) ^ ((cj + dj) * 19349663) ^ ((ck + dk) * 83492791)) & mask
                    a = head[h]
                    while a >= 0:
                        d = distance_5d(px, py, pz, nx, ny, nz, points[a, 0], points[a, 1], points[a, 2],
                                        normals[a, 0], normals[a, 1], normals[a, 2])
                        if d < radius:
                            ok = False
                            break
                        a = nxt[a]
                    if not ok:
                        break
        if ok:
            h = ((ci * 73856093) ^ (cj * 19349663) ^ (ck * 83492791)) & mask
            nxt[c] = head[h]
            head[h] = c
            accepted[count] = c
            count += 1
    return accepted[:count]


def dart_throw(points: np.ndarray, normals: np.ndarray, radius: float) -> np.ndarray:
    """Indices of the points kept by one pass of dart throwing at radius R, in visiting order."""
    bits = max(10, int(np.ceil(np.log2(4 * len(points)))))
    return _dart_throw(np.ascontiguousarray(points), np.ascontiguousarray(normals), float(radius), bits)


def sample_orientation_aware(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray,
                             nodes: int | None = 128, radius: float | None = None, seed: int = 0,
                             candidates_per_node: int = 48) -> tuple[np.ndarray, np.ndarray, float]:
    """Poisson-disk nodes on a mesh under the orientation-aware distance (Eq. 6): `sample_nodes` without the
    triangles the nodes lie on, (positions, node_normals, radius)."""
    s = sample_nodes(vertices, faces, normals, nodes, radius, seed, candidates_per_node)
    return s.positions, s.normals, s.radius


@dataclass(frozen=True)
class NodeSample:
    """Graph nodes sampled on a mesh: (N, 3) `positions` and unit `normals`, the (N,) `faces` (rows of the
    mesh's faces) they lie on, and the sampling `radius` R."""

    positions: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    radius: float


def sample_nodes(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray, nodes: int | None = 128,
                 radius: float | None = None, seed: int = 0, candidates_per_node: int = 48) -> NodeSample:
    """Poisson-disk nodes on a mesh under the orientation-aware distance (Eq. 6).

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int
    normals : (V, 3) float64 unit vertex normals
    nodes : int
        Target count N (R = sqrt(A / N), refined so the count lands within N ± 10 %).
    radius : float, optional
        Give R instead of N (a level of detail): one pass, N follows.
    seed : int
        The result is a function of the seed.

    Returns
    -------
    NodeSample: positions, normals, the triangles they lie on, and the R used.
    """
    rng = np.random.default_rng(seed)
    double_areas = face_double_areas(np.ascontiguousarray(vertices), np.ascontiguousarray(faces))
    area = 0.5 * double_areas.sum()
    if radius is not None:
        if not radius > 0:
            raise BadGraphError(f"radius must be positive, got {radius}")
        target = max(int(area / radius ** 2), 1)
    else:
        if nodes is None or nodes < 2:
            raise BadGraphError(f"nodes must be at least 2, got {nodes}")
        target = int(nodes)
    count = int(min(max(candidates_per_node * target, 2000), 400_000))
    points, point_normals, on = _surface_samples(vertices, faces, normals, count, rng, double_areas)
    # Shift to the origin so grid cell indices stay small integers.
    lowest = bounding_box(vertices)[0]
    points = points - lowest
    if radius is not None:
        keep = dart_throw(points, point_normals, radius)
        return NodeSample(points[keep] + lowest, point_normals[keep], on[keep], float(radius))

    r = float(np.sqrt(area / target))
    lo, hi = 0.0, np.inf
    best = None
    for _ in range(40):
        keep = dart_throw(points, point_normals, r)
        n = len(keep)
        if best is None or abs(n - target) < abs(len(best[0]) - target):
            best = (keep, r)
        if abs(n - target) <= 0.03 * target:
            break
        if n > target:
            lo = r
        else:
            hi = r
        r = np.sqrt(lo * hi) if np.isfinite(hi) and lo > 0 else (r * 1.3 if n > target else r / 1.3)
    keep, r = best
    if abs(len(keep) - target) > 0.1 * target:
        warnings.warn(f"orientation-aware sampling gave {len(keep)} nodes for a target of {target}: "
                      f"the surface does not hold more", stacklevel=2)
    return NodeSample(points[keep] + lowest, point_normals[keep], on[keep], float(r))
