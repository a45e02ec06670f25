"""Which way is up: a mesh stored Z-up (many scans and CAD exports) stood on its feet as +Y up.

glTF is +Y up by its specification. Other formats carry no convention, so the shape decides: a mesh stands
the way it would rest on a floor, its centre of mass above the polygon of the points that touch the floor
(a horse on its four hooves, not on its tail). The file's own +Y up wins whenever it is such a resting
pose; +Z up is taken only when +Y up would topple and +Z up would not.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..jit import njit
from .mesh import Mesh
from .normals import edges_and_cross, vertex_normals

CONTACT = 0.02  # points this close to the lowest, as a fraction of the height, touch the floor
Y_UP_BY_SPEC = (".glb", ".gltf", ".vrm")

# +Z up → +Y up is a quarter turn about +X the other way: (x, y, z) → (x, z, -y)
Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class Upright:
    """The up axis chosen for a mesh and why.

    Attributes
    ----------
    up : str
        "y" (as stored) or "z" (the file's +Z is turned to +Y).
    margins : dict
        For "y" and "z": how far the centre of mass lies inside the floor contact polygon, in units of
        the mesh's horizontal size (negative: outside, it would topple).
    reason : str
        One line for the page.
    """

    up: str
    margins: dict
    reason: str


def rotation_to_y_up(up: str) -> np.ndarray:
    """(3, 3) rotation taking the axis `up` ("y" or "z") of the stored mesh to +Y."""
    if up == "y":
        return np.eye(3)
    if up == "z":
        return Z_TO_Y.copy()
    raise ValueError(f"up must be 'y' or 'z', got {up!r}")


def area_centroid(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(3,) the surface's centre of mass (area-weighted triangle centres): a hollow shell's, which sits
    where a solid's does for the shapes that matter here and needs no closed surface."""
    # one pass over the faces: numpy's (F, 3, 3) temporaries took a third of a second on a 386k-vertex mesh
    total, moment = _area_moment(np.ascontiguousarray(vertices, dtype=np.float64), np.ascontiguousarray(faces))
    if total <= 0:
        return vertices.mean(axis=0)
    return moment / (3.0 * total)


@njit(cache=True)
def _area_moment(vertices, faces):
    # Σ twice-areas and Σ twice-area × (sum of the three corners)
    total = 0.0
    moment = np.zeros(3)
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        nx, ny, nz = edges_and_cross(vertices, a, b, c)[6:]
        w = np.sqrt(nx * nx + ny * ny + nz * nz)
        total += w
        for k in range(3):
            moment[k] += w * (vertices[a, k] + vertices[b, k] + vertices[c, k])
    return total, moment


def support_margin(vertices: np.ndarray, faces: np.ndarray, centre: np.ndarray | None = None) -> float:
    """How stably the mesh rests on the floor with +Y up: the signed distance of its centre of mass,
    projected on the floor, inside the convex polygon of the points within CONTACT of the lowest point,
    over the mesh's horizontal size. Negative when the centre lies outside: the mesh would topple.
    `centre`: the centre of mass when already known (it turns with the mesh)."""
    y = vertices[:, 1]
    height = float(np.ptp(y))
    if height <= 0:
        return 0.0
    floor = vertices[y <= y.min() + CONTACT * height][:, [0, 2]]
    centre = (area_centroid(vertices, faces) if centre is None else np.asarray(centre))[[0, 2]]
    size = float(np.max(np.ptp(vertices[:, [0, 2]], axis=0))) or 1.0
    try:
        hull = ConvexHull(floor)
    except (QhullError, ValueError):  # a point or a line of contact: no area to rest on
        return -float(np.min(np.linalg.norm(floor - centre, axis=1))) / size
    # hull.equations: n·p + d <= 0 inside; the margin is the least distance to an edge
    return float(-np.max(hull.equations[:, :2] @ centre + hull.equations[:, 2])) / size


def find_upright(mesh: Mesh, path: str = "") -> Upright:
    """The up axis `mesh` (as stored in the file `path`) stands on."""
    if str(path).lower().endswith(Y_UP_BY_SPEC):
        return Upright("y", {}, "glTF is +Y up")
    centre = area_centroid(mesh.vertices, mesh.faces)  # once: a turn moves it with the vertices
    margins = {up: support_margin(mesh.vertices @ rotation_to_y_up(up).T, mesh.faces, rotation_to_y_up(up) @ centre)
               for up in ("y", "z")}
    if margins["y"] < 0 <= margins["z"]:
        return Upright("z", margins, "stood up: +Z up, it would topple with +Y up")
    return Upright("y", margins, "+Y up, as stored")


def turned(mesh: Mesh, up: str) -> Mesh:
    """The mesh with its axis `up` turned to +Y."""
    if up == "y":
        return mesh
    vertices = mesh.vertices @ rotation_to_y_up(up).T
    return Mesh(vertices=vertices, faces=mesh.faces, normals=vertex_normals(vertices, mesh.faces), uvs=mesh.uvs,
                colors=mesh.colors, material=mesh.material, source=mesh.source)
