"""Cut the scanned object out of the scene (SPEC §5, patent claim 2).

plane : the dominant plane of a view (RANSAC) is the table or floor the object stands on; everything on or
        below it goes, and the largest connected component left is the object.
change : two scans of the same place, with and without the object. Near-surface voxels whose truncated signed
        distance changed by more than `threshold` (in units of the truncation distance) between the scans
        belong to the object; their largest 26-connected component is kept and the mesh is cut to it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import BadScanError
from .fuse import Voxels, open3d
from .surface import ScanMesh, keep_vertices, remove_small_components


@dataclass(frozen=True)
class Plane:
    """Points x with normal . x + offset = 0; `normal` (3,) unit, pointing to the side the camera was on."""

    normal: np.ndarray
    offset: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """(N,) signed distance of (N, 3) points, positive on the camera's side."""
        return points @ self.normal + self.offset


def dominant_plane(points: np.ndarray, viewpoint: np.ndarray, distance: float, seed: int = 0) -> Plane:
    """RANSAC plane with the most inliers among (N, 3) points (Open3D segment_plane), facing `viewpoint`."""
    if len(points) < 3:
        raise BadScanError("plane segmentation: the view has fewer than 3 depth points")
    o3d = open3d()
    o3d.utility.random.seed(seed)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, np.float64)))
    (a, b, c, d), _ = cloud.segment_plane(distance, 3, 500)
    normal = np.array([a, b, c])
    scale = np.linalg.norm(normal)
    plane = Plane(normal / scale, d / scale)
    if plane.distance(viewpoint[None])[0] < 0:
        plane = Plane(-plane.normal, -plane.offset)
    return plane


def remove_plane(mesh: ScanMesh, plane: Plane, margin: float) -> ScanMesh:
    """Drop everything within `margin` metres of the plane or behind it; keep the largest component."""
    above = plane.distance(mesh.vertices) > margin
    cut = keep_vertices(mesh, above)
    if len(cut.faces) == 0:
        raise BadScanError("plane segmentation: nothing is left above the dominant plane")
    return remove_small_components(cut, largest_only=True)


_NEIGHBOURS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                        if (i, j, k) > (0, 0, 0)], dtype=np.int64)  # half of the 26-neighbourhood


def _codes(keys: np.ndarray) -> np.ndarray:
    # pack integer voxel coordinates (|k| < 2^20) into one sortable int64
    k = keys.astype(np.int64) + (1 << 20)
    return (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]


def _lookup(sorted_codes: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """Index of each code in sorted_codes, or -1."""
    at = np.clip(np.searchsorted(sorted_codes, codes), 0, max(len(sorted_codes) - 1, 0))
    found = (len(sorted_codes) > 0) & (sorted_codes[at] == codes)
    return np.where(found, at, -1)


def largest_voxel_component(keys: np.ndarray) -> np.ndarray:
    """(M, 3) the largest 26-connected subset of the (N, 3) int64 voxel keys."""
    if len(keys) == 0:
        return keys
    codes = _codes(keys)
    order = np.argsort(codes)
    keys, codes = keys[order], codes[order]
    rows, cols = [], []
    for offset in _NEIGHBOURS:
        j = _lookup(codes, _codes(keys + offset))
        hit = j >= 0
        rows.append(np.flatnonzero(hit))
        cols.append(j[hit])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(keys), len(keys)))
    _, labels = connected_components(graph, directed=False)
    return keys[labels == np.argmax(np.bincount(labels))]


@dataclass(frozen=True)
class Change:
    """Result of change detection: the changed voxels and which scan holds the object.

    keys : (M, 3) int64 voxel keys of the largest changed component
    object_in_after : True when the object is present in the `after` scan (it appeared), False if removed
    """

    keys: np.ndarray
    object_in_after: bool


def seen_free(points: np.ndarray, views, margin: float) -> np.ndarray:
    """(N,) bool: some view saw through the (N, 3) world points, i.e. they lie more than `margin` metres in front
    of the depth that view measured. views : sequence of (depth (H, W) float32 m, pose (4, 4) camera-to-world,
    Intrinsics).

    A sparse TSDF stores only voxels near an observed surface, so empty space far from every surface is never
    allocated; the raw depth frames still say it was seen empty.
    """
    free = np.zeros(len(points), bool)
    for depth, pose, camera in views:
        h, w = depth.shape
        local = (points - pose[:3, 3]) @ pose[:3, :3]
        z = local[:, 2]
        ok = z > 0.05
        u = np.full(len(z), -1, np.int64)
        v = np.full(len(z), -1, np.int64)
        u[ok] = np.round(local[ok, 0] * camera.fx / z[ok] + camera.cx).astype(np.int64)
        v[ok] = np.round(local[ok, 1] * camera.fy / z[ok] + camera.cy).astype(np.int64)
        ok &= (u >= 0) & (u < w) & (v >= 0) & (v < h)
        measured = np.zeros(len(z), np.float32)
        measured[ok] = depth[v[ok], u[ok]]
        free |= ok & (measured > 0) & (z < measured - margin)
    return free


def _signed(voxels: Voxels, other: Voxels, other_views, min_weight: float) -> tuple[np.ndarray, ...]:
    """For the near-surface voxels of `voxels`: (keys, own tsdf, the other scan's tsdf, known mask)."""
    near = (voxels.weight >= min_weight) & (np.abs(voxels.tsdf) < 0.99)
    keys, own = voxels.keys[near], voxels.tsdf[near]
    codes = _codes(other.keys)
    order = np.argsort(codes)
    at = _lookup(codes[order], _codes(keys))
    theirs = np.ones(len(keys), np.float32)
    known = np.zeros(len(keys), bool)
    hit = at >= 0
    idx = order[at[hit]]
    observed = other.weight[idx] >= min_weight
    theirs[np.flatnonzero(hit)[observed]] = other.tsdf[idx[observed]]
    known[np.flatnonzero(hit)[observed]] = True
    # not stored by the other scan: known free (tsdf = +1) if its cameras saw through it
    rest = ~known
    centres = keys[rest] * voxels.voxel_size
    known[np.flatnonzero(rest)] = seen_free(centres, other_views, margin=2.0 * voxels.voxel_size)
    return keys, own, theirs, known


def changed_voxels(before: Voxels, after: Voxels, before_views=(), after_views=(), threshold: float = 0.5,
                   min_weight: float = 1.0) -> Change:
    """Near-surface voxels of either scan whose TSDF differs from the other scan's by more than `threshold`.

    The other scan's value is its stored TSDF, or +1 (free) where its depth frames (`*_views`, see `seen_free`)
    saw through the voxel; voxels neither scan knows are ignored. The largest 26-connected component is kept.
    """
    parts = []
    for mine, other, views, sign in ((after, before, before_views, 1.0), (before, after, after_views, -1.0)):
        keys, own, theirs, known = _signed(mine, other, views, min_weight)
        delta = sign * (own - theirs)  # after - before
        moved = known & (np.abs(delta) > threshold)
        parts.append((keys[moved], delta[moved]))
    keys = np.concatenate([p[0] for p in parts])
    delta = np.concatenate([p[1] for p in parts])
    if len(keys) == 0:
        raise BadScanError("change segmentation: the two scans do not differ anywhere they overlap "
                           "(was the object moved, and do the sweeps see the same place?)")
    keys, first = np.unique(keys, axis=0, return_index=True)
    delta = delta[first]
    component = largest_voxel_component(keys)
    inside = np.isin(_codes(keys), _codes(component))
    # Where the object is, its surface (small or negative TSDF) replaces free space (TSDF = +1).
    return Change(component, bool(np.mean(delta[inside]) < 0))


def cut_to_voxels(mesh: ScanMesh, keys: np.ndarray, voxel_size: float, dilation: int = 1) -> ScanMesh:
    """Keep the faces whose vertices lie within `dilation` voxels of the given keys; largest component."""
    grown = keys
    if dilation > 0:
        span = np.arange(-dilation, dilation + 1)
        offsets = np.stack(np.meshgrid(span, span, span, indexing="ij"), -1).reshape(-1, 3)
        grown = np.unique((keys[:, None, :] + offsets[None]).reshape(-1, 3), axis=0)
    codes = np.sort(_codes(grown))
    vertex_keys = np.round(mesh.vertices / voxel_size).astype(np.int64)
    cut = keep_vertices(mesh, _lookup(codes, _codes(vertex_keys)) >= 0)
    if len(cut.faces) == 0:
        raise BadScanError("change segmentation: no surface lies where the scans changed")
    return remove_small_components(cut, largest_only=True)
