"""Cut the scanned object out of the scene (KinÊtre paper, "Segmentation"; patent claim 2).

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
from .surface import ScanMesh, face_components, keep_faces, keep_vertices, remove_small_components


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


def cut_above_plane(mesh: ScanMesh, plane: Plane, margin: float) -> ScanMesh:
    """Drop everything within `margin` metres of the plane or behind it."""
    cut = keep_vertices(mesh, plane.distance(mesh.vertices) > margin)
    if len(cut.faces) == 0:
        raise BadScanError("plane segmentation: nothing is left above the dominant plane")
    return cut


def remove_plane(mesh: ScanMesh, plane: Plane, margin: float) -> ScanMesh:
    """Drop everything within `margin` metres of the plane or behind it; keep the largest component."""
    return remove_small_components(cut_above_plane(mesh, plane, margin), largest_only=True)


SPECK_JOINS = 4.0  # a 12-face, 2.8 cm scrap floated 1 cm from our lamp's shade; its broken-off shade is 16 cm
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


def group_components(mesh: ScanMesh, join: float) -> np.ndarray:
    """(F,) group label per face: connected components, merged when they come within `join` metres *(ours)*.

    A thin part fused a little thinner than it is (a 2 cm lamp arm at 6 mm voxels) can break the mesh into
    pieces a voxel or two apart; they are still one object. Vertices are binned into `join`-sized cells and
    components sharing a cell or a neighbouring one are merged (so the gap bridged is between join and 2 join).
    """
    labels = face_components(mesh.faces, len(mesh.vertices))
    if len(labels) == 0:
        return labels
    vertex_label = np.full(len(mesh.vertices), -1, np.int64)
    vertex_label[mesh.faces.reshape(-1)] = np.repeat(labels, 3)
    used = vertex_label >= 0
    cells = np.floor(mesh.vertices[used] / join).astype(np.int64)
    pairs = np.unique(np.c_[_codes(cells), vertex_label[used]], axis=0)  # (cell code, component)
    codes, owners = pairs[:, 0], pairs[:, 1]
    rows, cols = [owners], [owners]
    cell_keys = np.unique(cells, axis=0)
    # every component of a cell links to the cell's first one, and that one to the first of each neighbour
    # cell: together that connects all components that come close
    here = np.searchsorted(codes, _codes(cell_keys))
    for offset in _NEIGHBOURS:
        there = _codes(cell_keys + offset)
        b = np.searchsorted(codes, there)
        found = (b < len(codes)) & (codes[np.clip(b, 0, len(codes) - 1)] == there)
        rows.append(owners[here[found]])
        cols.append(owners[b[found]])
    first = np.searchsorted(codes, codes)
    rows.append(owners)
    cols.append(owners[first])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    n = int(labels.max()) + 1
    _, group = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)), directed=False)
    return group[labels]


def specks(mesh: ScanMesh, join: float) -> np.ndarray:
    """(F,) bool per face: its component (`face_components`) is under SPECK_JOINS `join` across (the
    diagonal of its bounding box)."""
    labels = face_components(mesh.faces, len(mesh.vertices))
    if len(labels) == 0:
        return np.zeros(0, bool)
    corners, owner = mesh.vertices[mesh.faces.reshape(-1)], np.repeat(labels, 3)
    low = np.full((labels.max() + 1, 3), np.inf)
    high = np.full((labels.max() + 1, 3), -np.inf)
    np.minimum.at(low, owner, corners)
    np.maximum.at(high, owner, corners)
    return np.linalg.norm(high - low, axis=1)[labels] < SPECK_JOINS * join


def remove_floaters(mesh: ScanMesh, min_fraction: float, join: float) -> tuple[ScanMesh, list[int]]:
    """Drop floaters; returns (kept mesh, face counts of what was dropped, largest first).

    Floaters are groups (`group_components`) with fewer faces than min_fraction of the largest group, and
    specks (`specks`: a few voxels of noise beside a surface, which the grouping would otherwise keep with it).
    A broken-off piece of a thin part is larger and stays with its object.
    """
    if len(mesh.faces) == 0:
        return mesh, []
    groups = group_components(mesh, join)
    counts = np.bincount(groups)
    small = counts[groups] < max(1.0, min_fraction * counts.max())
    labels = face_components(mesh.faces, len(mesh.vertices))
    drop = small | specks(mesh, join)
    dropped = np.bincount(labels[drop], minlength=labels.max() + 1)
    return keep_faces(mesh, ~drop), sorted(dropped[dropped > 0].tolist(), reverse=True)


def focus_point(poses: np.ndarray) -> np.ndarray | None:
    """(3,) the point closest (least squares) to the optical axes of the (N, 4, 4) camera poses, or None.

    A scan circles what it is about: the cameras keep it in view, so their axes pass near it. None when the
    axes are (nearly) parallel and fix no point.
    """
    if len(poses) < 2:
        return None
    a, b = np.zeros((3, 3)), np.zeros(3)
    for pose in poses:
        d = pose[:3, 2] / np.linalg.norm(pose[:3, 2])
        p = np.eye(3) - np.outer(d, d)
        a += p
        b += p @ pose[:3, 3]
    eigen = np.linalg.eigvalsh(a)
    if eigen[0] < 0.02 * len(poses):  # less than ~8 degrees of spread between the axes
        return None
    return np.linalg.solve(a, b)


@dataclass(frozen=True)
class Choice:
    """The object picked among the groups of a mesh, and why (for the scan report)."""

    mesh: ScanMesh
    sizes: list  # faces per group, largest first
    kept: int  # faces of the kept group
    reason: str


def select_object(mesh: ScanMesh, focus: np.ndarray | None, join: float, min_fraction: float = 0.05) -> Choice:
    """The group (`group_components`) the scan is about: among groups with at least min_fraction of the
    largest one's faces, the one nearest `focus` (see `focus_point`); the largest when there is no focus.

    Groups made only of specks (`specks`) are passed over while any other is left: `remove_floaters` would
    drop them whole, and a shrunken scene (a wrong depth scale) leaves such scraps right beside the focus.
    """
    groups = group_components(mesh, join)
    counts = np.bincount(groups)
    order = np.argsort(-counts)
    sizes = counts[order][counts[order] > 0].tolist()
    solid = np.bincount(groups[~specks(mesh, join)], minlength=len(counts)) > 0
    viable = [int(g) for g in order if counts[g] > 0 and solid[g]] or [int(order[0])]
    candidates = [g for g in viable if counts[g] >= min_fraction * counts[viable[0]]]
    if focus is None or len(sizes) == 1:
        best = viable[0]
        reason = "the only one" if len(sizes) == 1 else "the largest"
    else:
        from scipy.spatial import cKDTree
        distance = {}
        for g in candidates:
            points = mesh.vertices[np.unique(mesh.faces[groups == g])]
            distance[g] = float(cKDTree(points).query(focus)[0])
        best = min(candidates, key=distance.get)
        reason = (f"nearest to the point the cameras looked at ({distance[best] * 100:.0f} cm away; "
                  f"the next is {sorted(distance.values())[1] * 100:.0f} cm away)" if len(candidates) > 1 else
                  f"the only one with at least {min_fraction:.0%} of the largest one's faces")
    passed = len(sizes) - len(viable) if solid.any() else 0
    if passed:
        reason += f"; passed over {passed} made only of specks (pieces under {SPECK_JOINS * join * 100:.1f} cm)"
    return Choice(keep_faces(mesh, groups == best), sizes, int(counts[best]), reason)


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
