"""Mesh import and cleanup (trimesh): any common file in, one clean `Mesh` out."""
from __future__ import annotations

import gzip
import io
import os
import warnings

import numpy as np

from ..errors import BadMeshError
from .mesh import Mesh
from .normals import vertex_normals

# trimesh's own names for the formats we accept; ".ply.gz" etc. are decompressed first.
FORMATS = {"obj": "obj", "ply": "ply", "stl": "stl", "off": "off", "glb": "glb", "gltf": "gltf"}


def _file_type(path: str) -> tuple[str, bool]:
    name = os.path.basename(path).lower()
    gz = name.endswith(".gz")
    if gz:
        name = name[:-3]
    ext = name.rsplit(".", 1)[-1] if "." in name else ""
    if ext not in FORMATS:
        raise BadMeshError(f"{path}: unsupported mesh format {ext!r} (expected one of "
                           f"{', '.join(sorted(FORMATS))}, optionally gzipped)")
    return FORMATS[ext], gz


def load_mesh(path: str | os.PathLike) -> Mesh:
    """Read a triangle mesh from OBJ, PLY, STL, OFF, GLB or glTF and clean it.

    Scenes (glTF, multi-object OBJ) are flattened with their node transforms. Vertices are welded
    by position (keeping UV seams), degenerate and duplicate faces and unreferenced vertices are
    dropped. Open, one-sided, holed and multi-component meshes are accepted as they are.

    Raises
    ------
    BadMeshError
        Missing or unreadable file, no faces (a point cloud), NaN/Inf coordinates, zero area.
    """
    import trimesh

    path = os.fspath(path)
    if not os.path.exists(path):
        raise BadMeshError(f"{path}: file not found")
    if os.path.isdir(path):
        raise BadMeshError(f"{path}: is a directory, not a mesh file")
    file_type, gz = _file_type(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
        if gz:
            data = gzip.decompress(data)
    except (OSError, EOFError) as exc:
        raise BadMeshError(f"{path}: cannot read file ({exc})") from None
    if not data.strip():
        raise BadMeshError(f"{path}: file is empty")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # glTF with external buffers needs the folder to resolve them.
            resolver = trimesh.resolvers.FilePathResolver(path) if file_type == "gltf" else None
            loaded = trimesh.load(io.BytesIO(data), file_type=file_type, process=False, resolver=resolver)
    except Exception as exc:  # trimesh raises many types on corrupt files; each becomes one message
        raise BadMeshError(f"{path}: cannot parse {file_type.upper()} ({type(exc).__name__}: {exc})") from None
    return mesh_from_trimesh(loaded, path)


def mesh_from_trimesh(loaded, source: str = "") -> Mesh:
    """Clean a trimesh `Trimesh`/`Scene`/`PointCloud` into a `Mesh` (see `load_mesh`)."""
    import trimesh

    label = source or "mesh"
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        if not geoms:
            raise BadMeshError(f"{label}: the scene holds no triangles (a point cloud or empty file)")
        loaded = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
    if not isinstance(loaded, trimesh.Trimesh):
        raise BadMeshError(f"{label}: holds no triangles (got a {type(loaded).__name__}, e.g. a point cloud)")
    tm = loaded
    if len(tm.faces) == 0:
        raise BadMeshError(f"{label}: has no faces (a point cloud or empty mesh)")
    if not np.isfinite(tm.vertices).all():
        bad = int((~np.isfinite(tm.vertices).all(axis=1)).sum())
        raise BadMeshError(f"{label}: {bad} vertices have NaN or infinite coordinates")

    tm = tm.copy()
    tm.merge_vertices()  # by position; vertices with different UVs stay apart
    tm.update_faces(tm.nondegenerate_faces(height=None))
    tm.update_faces(tm.unique_faces())
    tm.remove_unreferenced_vertices()
    if len(tm.faces) == 0:
        raise BadMeshError(f"{label}: every face is degenerate (zero area)")
    vertices = np.ascontiguousarray(tm.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(tm.faces, dtype=np.int32)
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    scale = float(np.ptp(vertices, axis=0).max())
    if not area > 1e-12 * max(scale, 1e-300) ** 2:
        raise BadMeshError(f"{label}: total surface area is zero (all faces are flat lines or points)")

    uvs = colors = material = None
    visual = tm.visual
    if getattr(visual, "kind", None) == "texture":
        if visual.uv is not None and len(visual.uv) == len(vertices):
            uvs = np.ascontiguousarray(visual.uv, dtype=np.float32)
        material = getattr(visual, "material", None)
    elif getattr(visual, "kind", None) == "vertex":
        colors = np.ascontiguousarray(visual.vertex_colors, dtype=np.uint8)
    return Mesh(vertices=vertices, faces=faces, normals=vertex_normals(vertices, faces, weld=uvs is not None), uvs=uvs,
                colors=colors, material=material, source=source)
