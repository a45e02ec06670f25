"""Mesh import and cleanup (trimesh): any common file in, one clean `Mesh` out."""
from __future__ import annotations

import gzip
import io
import os
import warnings
import zlib

import numpy as np

from ..errors import BadMeshError
from ..lazy import import_trimesh
from .mesh import Mesh, bounding_box
from .clean import clean
from .normals import normals_and_area

# trimesh's own names for the formats we accept; ".ply.gz" etc. are decompressed first.
FORMATS = {"obj": "obj", "ply": "ply", "stl": "stl", "off": "off", "glb": "glb", "gltf": "gltf"}
# a gzipped mesh may expand to at most this: a few-kB "gzip bomb" must not take all memory
MAX_GUNZIPPED = 1 << 30


def _gunzip(data: bytes, path: str) -> bytes:
    with gzip.GzipFile(fileobj=io.BytesIO(data)) as fh:
        out = fh.read(MAX_GUNZIPPED + 1)
    if len(out) > MAX_GUNZIPPED:
        raise BadMeshError(f"{path}: decompresses to more than {MAX_GUNZIPPED >> 30} GiB")
    return out


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
    trimesh = import_trimesh()

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
            data = _gunzip(data, path)
    except (OSError, EOFError, zlib.error) as exc:
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
    trimesh = import_trimesh()

    label = source or "mesh"
    if isinstance(loaded, trimesh.Scene):
        for g in loaded.geometry.values():
            if isinstance(g, trimesh.Trimesh):
                check_indexed(g.vertices, g.faces, label)
        try:
            dumped = loaded.dump()
        except Exception as exc:  # a scene graph trimesh cannot flatten (bad node references, transforms)
            raise BadMeshError(f"{label}: cannot flatten the scene ({type(exc).__name__}: {exc})") from None
        geoms = [g for g in dumped if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        if not geoms:
            raise BadMeshError(f"{label}: the scene holds no triangles (a point cloud or empty file)")
        loaded = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
    if not isinstance(loaded, trimesh.Trimesh):
        raise BadMeshError(f"{label}: holds no triangles (got a {type(loaded).__name__}, e.g. a point cloud)")
    tm = loaded
    check_indexed(tm.vertices, tm.faces, label)
    if len(tm.faces) == 0:
        raise BadMeshError(f"{label}: has no faces (a point cloud or empty mesh)")
    if not np.isfinite(tm.vertices).all():
        bad = int((~np.isfinite(tm.vertices).all(axis=1)).sum())
        raise BadMeshError(f"{label}: {bad} vertices have NaN or infinite coordinates")

    tm = clean(tm)  # weld by position (UV seams stay apart), drop degenerate/duplicate faces, unused vertices
    if len(tm.faces) == 0:
        raise BadMeshError(f"{label}: every face is degenerate (zero area)")
    vertices = np.array(tm.vertices, dtype=np.float64, order="C")  # a copy: `loaded` may be the caller's
    faces = np.array(tm.faces, dtype=np.int32, order="C")
    uvs = uvs_of(tm.visual, len(vertices))
    normals, area = normals_and_area(vertices, faces, weld=uvs is not None)
    scale = float(np.ptp(bounding_box(vertices), axis=0).max())
    if not area > 1e-12 * max(scale, 1e-300) ** 2:
        raise BadMeshError(f"{label}: total surface area is zero (all faces are flat lines or points)")

    colors = material = None
    visual = tm.visual
    if getattr(visual, "kind", None) == "texture":
        material = getattr(visual, "material", None)
    elif getattr(visual, "kind", None) == "vertex":
        colors = np.ascontiguousarray(visual.vertex_colors, dtype=np.uint8)
    return Mesh(vertices=vertices, faces=faces, normals=normals, uvs=uvs, colors=colors, material=material,
                source=source)


def check_indexed(vertices, faces, label: str) -> None:
    """Refuse faces that are not (F, 3) integer rows naming existing vertices, before anything indexes by them
    (the compiled cleanup and normal kernels read vertices[faces] unchecked)."""
    vertices, faces = np.asarray(vertices), np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise BadMeshError(f"{label}: vertices are not x, y, z rows (shape {vertices.shape})")
    if faces.size == 0:
        return
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.dtype.kind not in "iu":
        raise BadMeshError(f"{label}: faces are not triangles of vertex indices (shape {faces.shape}, "
                           f"{faces.dtype})")
    lo, hi = int(faces.min()), int(faces.max())
    if lo < 0 or hi >= len(vertices):
        bad = lo if lo < 0 else hi
        raise BadMeshError(f"{label}: a face names vertex {bad}, but the mesh has {len(vertices)} vertices")


def uvs_of(visual, count: int) -> np.ndarray | None:
    """(count, 2) float32 texture coordinates of a trimesh visual, or None."""
    if getattr(visual, "kind", None) == "texture" and visual.uv is not None and len(visual.uv) == count:
        return np.ascontiguousarray(visual.uv, dtype=np.float32)
    return None
