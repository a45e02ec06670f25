"""The `Mesh` dataclass: a cleaned triangle mesh, the input of every later stage."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np


def column_bounds(rows: np.ndarray) -> tuple[list, list]:
    """Per-column minima and maxima of (n, k) rows as Python numbers (ints for integer data; NaN where a
    column holds one), column by column: numpy's min(axis=0) over rows of three or four strides across
    memory and is much slower."""
    columns = rows.reshape(rows.shape[0], -1).T
    return [column.min().item() for column in columns], [column.max().item() for column in columns]


def bounding_box(points: np.ndarray) -> np.ndarray:
    """(2, 3) float64: min and max corners of (n, 3) points (NaN where a coordinate is NaN)."""
    return np.array(column_bounds(points), dtype=float)


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh after import and cleanup.

    Attributes
    ----------
    vertices : (V, 3) float64
        Positions in the file's own units. Vertices are welded by position except across UV seams,
        where the copies keep their own texture coordinates (as a glTF player needs them).
    faces : (F, 3) int32
        Triangles, indices into `vertices`; no degenerate or duplicate faces.
    normals : (V, 3) float64
        Unit area-weighted vertex normals (seam copies share the welded normal).
    uvs : (V, 2) float32 or None
        Texture coordinates where the input had them.
    colors : (V, 4) uint8 or None
        Vertex colours where the input had them.
    material : object or None
        The trimesh material of the input (kept for glTF export), or None.
    source : str
        The path the mesh was read from ("" when built in memory).

    Derived data (`pieces`) is computed on first use and kept with the mesh, so its arrays must not be
    changed in place.
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray | None = None
    colors: np.ndarray | None = None
    material: object | None = field(default=None, repr=False)
    source: str = ""

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64: min and max corners."""
        return bounding_box(self.vertices)

    @property
    def diagonal(self) -> float:
        """Length of the bounding-box diagonal."""
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @property
    def face_areas(self) -> np.ndarray:
        """(F,) float64 triangle areas."""
        v = self.vertices[self.faces]
        return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)

    @property
    def area(self) -> float:
        return float(self.face_areas.sum())

    def scaled(self, factor: float) -> Mesh:
        """The mesh scaled by `factor` about the origin (uniform scaling keeps its normals), with what it has
        computed once (its pieces) carried over."""
        out = dataclasses.replace(self, vertices=self.vertices * factor)
        if "pieces" in vars(self):
            vars(out)["pieces"] = self.pieces.scaled(factor)
        return out

    @cached_property
    def pieces(self):
        """`MeshPieces`: the mesh's connected pieces, each vertex's piece, and the inside and contact tests
        between them, computed once."""
        from .pieces import MeshPieces  # it builds on this module
        return MeshPieces(self.vertices, self.faces)
