"""The scanned surface as a clean mesh: components, floaters, decimation, outward normals, output frame, files.

Marching cubes itself runs in `fuse.TSDFVolume.triangle_mesh`; everything here works on plain arrays
(vertices (V, 3) float64 metres, faces (F, 3) int64, colours (V, 3) float32 in [0, 1]).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import ExportError

MESH_SUFFIXES = (".ply", ".obj", ".glb")
# Camera frames are x right, y down, z forward; Kinetre meshes are +Y up with the viewer on +Z:
# a half turn about x maps one to the other.
CAMERA_TO_Y_UP = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass(frozen=True)
class ScanMesh:
    """vertices (V, 3) float64 metres, faces (F, 3) int64, colors (V, 3) float32 in [0, 1]."""

    vertices: np.ndarray
    faces: np.ndarray
    colors: np.ndarray

    def transformed(self, transform: np.ndarray) -> "ScanMesh":
        """Apply a rigid (4, 4) transform (orientation of faces is kept: rotations don't mirror)."""
        return ScanMesh(self.vertices @ transform[:3, :3].T + transform[:3, 3], self.faces, self.colors)


def face_components(faces: np.ndarray, vertex_count: int) -> np.ndarray:
    """(F,) int label of the connected component (through shared vertices) of each face."""
    if len(faces) == 0:
        return np.zeros(0, np.int64)
    rows = np.repeat(np.arange(len(faces)), 3)
    graph = coo_matrix((np.ones(len(rows)), (rows, faces.reshape(-1))), shape=(len(faces), vertex_count))
    # faces are linked when they share a vertex: components of the face-vertex incidence (bipartite) graph
    n = len(faces) + vertex_count
    bip = coo_matrix((graph.data, (graph.row, graph.col + len(faces))), shape=(n, n))
    _, labels = connected_components(bip, directed=False)
    return labels[: len(faces)]


def keep_faces(mesh: ScanMesh, keep: np.ndarray) -> ScanMesh:
    """The sub-mesh of faces where `keep` (F,) bool is true, unused vertices dropped."""
    faces = mesh.faces[keep]
    used = np.unique(faces)
    remap = np.full(len(mesh.vertices), -1, np.int64)
    remap[used] = np.arange(len(used))
    return ScanMesh(mesh.vertices[used], remap[faces], mesh.colors[used])


def keep_vertices(mesh: ScanMesh, keep: np.ndarray) -> ScanMesh:
    """The sub-mesh of faces whose three vertices all have `keep` (V,) bool true."""
    return keep_faces(mesh, np.all(keep[mesh.faces], axis=1))


def remove_small_components(mesh: ScanMesh, min_fraction: float = 0.02, largest_only: bool = False) -> ScanMesh:
    """Drop floaters: components with fewer faces than min_fraction of the largest (or all but the largest)."""
    if len(mesh.faces) == 0:
        return mesh
    labels = face_components(mesh.faces, len(mesh.vertices))
    counts = np.bincount(labels)
    if largest_only:
        keep = labels == np.argmax(counts)
    else:
        keep = counts[labels] >= max(1.0, min_fraction * counts.max())
    return keep_faces(mesh, keep)


def component_count(mesh: ScanMesh) -> int:
    """Number of connected components."""
    return int(len(np.unique(face_components(mesh.faces, len(mesh.vertices))))) if len(mesh.faces) else 0


def _legacy(mesh: ScanMesh):
    from .fuse import open3d
    o3d = open3d()
    legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices),
                                       o3d.utility.Vector3iVector(mesh.faces.astype(np.int32)))
    legacy.vertex_colors = o3d.utility.Vector3dVector(mesh.colors.astype(np.float64))
    return legacy


def decimate(mesh: ScanMesh, target_faces: int) -> ScanMesh:
    """Quadric edge-collapse decimation (Garland & Heckbert) down to about `target_faces` faces."""
    if target_faces <= 0 or len(mesh.faces) <= target_faces:
        return mesh
    small = _legacy(mesh).simplify_quadric_decimation(int(target_faces))
    small.remove_unreferenced_vertices()
    return ScanMesh(np.asarray(small.vertices, np.float64), np.asarray(small.triangles, np.int64),
                    np.clip(np.asarray(small.vertex_colors, np.float32), 0.0, 1.0))


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) area-weighted (unnormalised) face normals, right-handed winding."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return np.cross(b - a, c - a)


def orient_outward(mesh: ScanMesh, viewpoints: np.ndarray) -> ScanMesh:
    """Flip the winding if most of the surface (by area) faces away from the cameras that saw it.

    A scanned surface was seen from outside, so its outward normals point toward the nearest viewpoint
    ((C, 3) camera centres). The vote is area weighted, so a few noisy faces cannot flip the mesh.
    """
    if len(mesh.faces) == 0 or len(viewpoints) == 0:
        return mesh
    normals = face_normals(mesh.vertices, mesh.faces)
    centroids = mesh.vertices[mesh.faces].mean(axis=1)
    from scipy.spatial import cKDTree
    _, nearest = cKDTree(viewpoints).query(centroids)
    toward = viewpoints[nearest] - centroids
    if np.sum(np.einsum("ij,ij->i", normals, toward) / (np.linalg.norm(toward, axis=1) + 1e-12)) < 0:
        return ScanMesh(mesh.vertices, mesh.faces[:, ::-1].copy(), mesh.colors)
    return mesh


def write_mesh(mesh: ScanMesh, path: str | Path) -> Path:
    """Write PLY, OBJ or GLB (by suffix) with vertex colours. Raises ExportError for other suffixes."""
    import trimesh
    path = Path(path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise ExportError(f"{path}: scan output must end in {', '.join(MESH_SUFFIXES)}")
    colors = np.concatenate([np.round(mesh.colors * 255).astype(np.uint8),
                             np.full((len(mesh.colors), 1), 255, np.uint8)], axis=1)
    out = trimesh.Trimesh(mesh.vertices, mesh.faces, vertex_colors=colors, process=False)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        out.export(path)
    except OSError as exc:
        raise ExportError(f"{path}: cannot write the scanned mesh ({exc})") from None
    return path
