"""Mesh cleanup (weld by position, drop degenerate/duplicate faces and unreferenced vertices), fast
when there is nothing to clean.

trimesh's `merge_vertices`, `nondegenerate_faces`, `unique_faces` and `remove_unreferenced_vertices` sort
every vertex and face (seconds on a million-vertex mesh) even when they change nothing, which is the usual
case for a scanned or exported mesh. `clean` first checks, in one linear pass each, whether each of them
would be a no-op — by the same criteria, on the same rounded values — and only runs trimesh's when one of
them would change the mesh. The result is the mesh trimesh's cleanup gives either way.
"""
from __future__ import annotations

import numpy as np

from ..jit import njit
from .normals import edges_and_cross

# trimesh's default tolerance (tol.merge) for welding and degenerate faces
_MARGIN = 1.0 + 1e-6  # a face this close to trimesh's threshold is left to trimesh's own test


@njit(cache=True)
def _rounded_rows_distinct(values, scales):
    """True if no two rows of round(values * scales) (numpy's round half to even, as int64) are equal: an
    open-addressing hash set, O(n), rounding on the fly rather than in (n, k) temporaries."""
    n, k = values.shape
    size = 1
    while size < 2 * n:
        size *= 2
    mask = size - 1
    table = np.full(size, -1, np.int64)
    for r in range(n):
        h = np.uint64(1469598103934665603)
        for c in range(k):
            h = (h ^ np.uint64(np.int64(np.rint(values[r, c] * scales[c])))) * np.uint64(1099511628211)
            h ^= h >> np.uint64(29)
        slot = np.int64(h & np.uint64(mask))
        while table[slot] >= 0:
            other = table[slot]
            same = True
            for c in range(k):
                if np.int64(np.rint(values[other, c] * scales[c])) != np.int64(np.rint(values[r, c] * scales[c])):
                    same = False
                    break
            if same:
                return False
            slot = (slot + 1) & mask
        table[slot] = r
    return True


@njit(cache=True)
def _sorted_rows_distinct(ordered, nv):
    """True if no two rows of the (F, 3) corners, each sorted ascending and below `nv`, are equal: a counting
    sort by the first corner, then the few faces that share it compared directly (faster than hashing
    every row: the buckets are filled and read in order, the hash table at random)."""
    nf = ordered.shape[0]
    start = np.zeros(nv + 1, np.int64)
    for f in range(nf):
        start[ordered[f, 0] + 1] += 1
    for a in range(nv):
        start[a + 1] += start[a]
    fill = start[:-1].copy()
    rest = np.empty(nf, np.int64)  # the other two corners as one number
    for f in range(nf):
        a = ordered[f, 0]
        rest[fill[a]] = ordered[f, 1] * nv + ordered[f, 2]
        fill[a] += 1
    for a in range(nv):
        lo, hi = start[a], start[a + 1]
        if hi - lo > 16:  # a fan around one vertex: sort rather than compare every pair
            run = np.sort(rest[lo:hi])
            for q in range(1, run.shape[0]):
                if run[q] == run[q - 1]:
                    return False
        else:
            for p in range(lo, hi):
                for q in range(p + 1, hi):
                    if rest[p] == rest[q]:
                        return False
    return True


@njit(cache=True)
def _faces_fine(vertices, faces, height):
    """True if every face is clearly non-degenerate by trimesh's test (both heights of its 2D bounding box,
    2·area / edge, above `height`, with margin), its sorted corners are distinct from every other face's and
    every vertex is used."""
    nf = faces.shape[0]
    used = np.zeros(vertices.shape[0], np.bool_)
    limit = height * _MARGIN
    for f in range(nf):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        used[a] = True
        used[b] = True
        used[c] = True
        ux, uy, uz, vx, vy, vz, nx, ny, nz = edges_and_cross(vertices, a, b, c)
        area2 = np.sqrt(nx * nx + ny * ny + nz * nz)
        lu = np.sqrt(ux * ux + uy * uy + uz * uz)
        lv = np.sqrt(vx * vx + vy * vy + vz * vz)
        if not (lu > limit and lv > limit and area2 > limit * lu and area2 > limit * lv):
            return False
    for v in range(used.shape[0]):
        if not used[v]:
            return False
    ordered = np.empty((nf, 3), np.int64)
    for f in range(nf):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        if a > b:
            a, b = b, a
        if b > c:
            b, c = c, b
        if a > b:
            a, b = b, a
        ordered[f, 0], ordered[f, 1], ordered[f, 2] = a, b, c
    return _sorted_rows_distinct(ordered, vertices.shape[0])


def is_clean(tm) -> bool:
    """Whether trimesh's merge_vertices / nondegenerate_faces / unique_faces / remove_unreferenced_vertices
    would all leave the `trimesh.Trimesh` unchanged (the keys trimesh welds by, rounded as it rounds them)."""
    from trimesh import tol, util

    vertices = np.asarray(tm.vertices, dtype=np.float64)
    faces = np.asarray(tm.faces)
    if len(vertices) == 0 or len(faces) == 0:
        return False
    if not _faces_fine(np.ascontiguousarray(vertices), np.ascontiguousarray(faces, dtype=np.int64), tol.merge):
        return False
    # trimesh.grouping.merge_vertices's key: position (and UV, and cached normals) rounded to its digits
    stacked, scales = [vertices], [10.0 ** util.decimal_to_digits(tol.merge)] * 3
    visual = tm.visual
    if visual.defined and visual.kind == "texture" and visual.uv is not None and len(visual.uv) == len(vertices):
        stacked.append(visual.uv)
        scales += [10.0 ** 4] * 2
    normals = tm._cache["vertex_normals"]
    if np.shape(normals) == vertices.shape:
        stacked.append(normals)
        scales += [10.0 ** 2] * 3
    values = stacked[0] if len(stacked) == 1 else np.column_stack(stacked)
    return bool(_rounded_rows_distinct(np.ascontiguousarray(values, dtype=np.float64), np.array(scales)))


def clean(tm):
    """The cleaned mesh: `tm` itself when there is nothing to clean, else a cleaned copy."""
    if is_clean(tm):
        return tm
    tm = tm.copy()
    tm.merge_vertices()  # by position; vertices with different UVs stay apart
    tm.update_faces(tm.nondegenerate_faces(height=None))
    tm.update_faces(tm.unique_faces())
    tm.remove_unreferenced_vertices()
    return tm
