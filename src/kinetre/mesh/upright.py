"""Which way is up: a mesh stored with another axis up (+Z from CAD and scan tools, now and then ±X or
upside down) stood on its feet as +Y up.

glTF is +Y up by its specification. Other formats carry no convention, so the shape decides. Each of the six
axis directions is a candidate up, scored by the cues a person standing the mesh on a table would use:

- it rests: a face of the convex hull under that side carries the centre of mass (the centre projects
  inside the polygon of the points on that face), and the further the mesh can tip before it topples, the
  better (a horse on its four hooves, not on its tail);
- it rests square: that face is level, not leaning (a file's up is along an axis);
- it does not lie flat: a side lower than half its footprint is a figure lying down (a person on their
  back rests very well, yet is not standing);
- a mirror plane is vertical: the axis across the mesh's left-right symmetry is never up;
- the file's convention: +Z up is the other common one.

The stored +Y up is kept whenever it rests square and no other axis is clearly better, so a mesh that
stands as stored is never turned.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

from ..jit import njit
from .mesh import Mesh
from .normals import edges_and_cross, vertex_normals

Y_UP_BY_SPEC = (".glb", ".gltf", ".vrm")
AXES = ("y", "z", "x", "-x", "-y", "-z")  # the stored axis that is up; "y" leaves the mesh as it is

# the proper rotation taking each stored axis to +Y (a quarter turn about Z or X, or half a turn about X)
TURNS = {
    "y": np.eye(3),
    "z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),   # (x, y, z) -> (x, z, -y)
    "-z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
    "x": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),   # (x, y, z) -> (-y, x, z)
    "-x": np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "-y": np.diag([1.0, -1.0, -1.0]),
}

CONTACT = 0.01      # points this close to a resting face's plane, over the mesh's diagonal, touch the floor
LEAN = 30.0         # degrees: a resting face this far from level still counts as standing on that axis
HULL_POINTS = 10000  # the hull of this many of the vertices (and the extremes) decides as well as all of them
MIRROR_POINTS = 4000
# the score: tipping and leaning per 30 degrees, a side lying flat per unit of log(height / footprint)
# below log(1/2), an axis across a mirror plane, the +Z-up convention; +Y kept unless beaten by KEEP
TIP, TIP_CAP, LEANING, FLAT, FLAT_BELOW, ACROSS_MIRROR, Z_CONVENTION, KEEP = 0.5, 45.0, 1.0, 3.0, -0.7, 1.0, 0.1, 0.6
STANDS = -0.3       # a score below this stands nowhere well (a figure mid-stride): the file's axes are kept
SQUARE = 15.0       # degrees: the stored +Y up is kept only when its face leans less than this
MIRRORED = 0.005    # a mirror error (over the diagonal) this much below the other planes' marks a mirror plane


@dataclass(frozen=True)
class Upright:
    """The up axis chosen for a mesh and why.

    Attributes
    ----------
    up : str
        The stored axis turned to +Y: one of AXES ("y": as stored, "z": a +Z-up file, ...).
    scores : dict
        Per candidate axis the score it was chosen by (-inf: the mesh topples with that side up; empty when
        nothing was weighed: glTF, or a choice made by hand).
    reason : str
        One line for the page.
    """

    up: str
    scores: dict
    reason: str


def rotation_to_y_up(up: str) -> np.ndarray:
    """(3, 3) rotation taking the stored axis `up` (one of AXES) to +Y."""
    if up not in TURNS:
        raise ValueError(f"up must be one of {', '.join(AXES)}, got {up!r}")
    return TURNS[up].copy()


def axis_name(up: str) -> str:
    """"+Z" for "z", "-X" for "-x": an axis of AXES as the page and the summary write it."""
    return up.upper() if up.startswith("-") else f"+{up.upper()}"


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


def bounds(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(3,) the lowest and highest coordinate per axis and (3,) the vertices holding them, in one pass
    (numpy's min and max along the first axis of an (N, 3) array are two strided passes each)."""
    return _bounds(np.ascontiguousarray(vertices, dtype=np.float64))


@njit(cache=True)
def _bounds(vertices):
    lo, hi = vertices[0].copy(), vertices[0].copy()
    at_lo, at_hi = np.zeros(3, np.int64), np.zeros(3, np.int64)
    for i in range(1, vertices.shape[0]):
        for k in range(3):
            x = vertices[i, k]
            if x < lo[k]:
                lo[k], at_lo[k] = x, i
            elif x > hi[k]:
                hi[k], at_hi[k] = x, i
    return lo, hi, at_lo, at_hi


def resting_faces(vertices: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The faces of the convex hull the mesh can rest on: (R, 3) their outward normals (pointing at the
    floor) and (R,) how far, in degrees, the mesh tips on each before its centre of mass passes the edge
    of the floor contact (the points within CONTACT of the face's plane). Empty for a flat or tiny mesh."""
    v = np.asarray(vertices, dtype=np.float64)
    none = np.zeros((0, 3)), np.zeros(0)
    if len(v) < 4:
        return none
    lo, hi, at_lo, at_hi = bounds(v)
    diagonal = float(np.linalg.norm(hi - lo))
    if diagonal <= 0:
        return none
    step = max(1, len(v) // HULL_POINTS)
    points = np.vstack([v[::step], v[at_lo], v[at_hi]])
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):  # all in a plane: no solid to stand
        return none
    normal, offset = hull.equations[:, :3], hull.equations[:, 3]
    depth = -(normal @ centre + offset)  # the centre's height over each face's plane
    foot = centre + depth[:, None] * normal
    a, b, c = (hull.points[hull.simplices[:, k]] for k in range(3))
    sides = [np.einsum("ij,ij->i", np.cross(q - p, foot - p), normal) for p, q in ((a, b), (b, c), (c, a))]
    tol = -1e-12 * diagonal ** 2
    inside = np.all([s >= tol for s in sides], axis=0) | np.all([s <= -tol for s in sides], axis=0)
    corners = hull.points[hull.vertices]
    normals, tipping = [], []
    for f in np.flatnonzero(inside & (depth > 0)):
        touching = corners[corners @ normal[f] + offset[f] >= -CONTACT * diagonal]
        across = np.cross(normal[f], np.eye(3)[int(np.argmin(np.abs(normal[f])))])
        across /= np.linalg.norm(across)
        basis = np.stack([across, np.cross(normal[f], across)], axis=1)
        margin = _inside_margin(touching @ basis, foot[f] @ basis)
        normals.append(normal[f])
        tipping.append(np.degrees(np.arctan2(margin, depth[f])))
    return (np.array(normals), np.array(tipping)) if normals else none


def _inside_margin(polygon: np.ndarray, point: np.ndarray) -> float:
    """The distance of `point` inside the convex hull of the 2-D `polygon` points (0 on or without area)."""
    try:
        hull = ConvexHull(polygon)
    except (QhullError, ValueError):  # a point or a line of contact: it balances on an edge
        return 0.0
    return max(0.0, float(-np.max(hull.equations[:, :2] @ point + hull.equations[:, 2])))


def mirror_errors(vertices: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(3,) how far the mesh is from its mirror image across the plane through `centre` normal to x, y and
    z: the median distance from a mirrored vertex to the nearest vertex, over the diagonal (0: symmetric)."""
    v = np.asarray(vertices, dtype=np.float64)
    lo, hi = bounds(v)[:2]
    diagonal = float(np.linalg.norm(hi - lo)) or 1.0
    step = max(1, len(v) // MIRROR_POINTS)
    tree = cKDTree(v[::step])
    probe = v[step // 2::step]
    errors = np.empty(3)
    for k in range(3):
        mirrored = probe.copy()
        mirrored[:, k] = 2.0 * centre[k] - mirrored[:, k]
        errors[k] = np.median(tree.query(mirrored)[0]) / diagonal
    return errors


def _mirror_normal(errors: np.ndarray) -> int | None:
    """The axis across the mesh's one clear mirror plane (None: no plane, or several, as for a ball)."""
    k = int(np.argmin(errors))
    runner_up = float(np.sort(errors)[1])
    return k if errors[k] <= 0.5 * runner_up and runner_up - errors[k] >= MIRRORED else None


def axis_scores(vertices: np.ndarray, faces: np.ndarray) -> tuple[dict, dict]:
    """Per candidate axis (AXES): its score (-inf when the mesh topples with that side up) and the lean of
    the face it would stand on, in degrees."""
    v = np.asarray(vertices, dtype=np.float64)
    centre = area_centroid(v, faces)
    normals, tipping = resting_faces(v, centre)
    lo, hi = bounds(v)[:2]
    extent = hi - lo
    across = _mirror_normal(mirror_errors(v, centre)) if len(v) >= 4 else None
    scores, leans = {}, {}
    for up in AXES:
        k, sign = "xyz".index(up[-1]), (-1.0 if up.startswith("-") else 1.0)
        lean = np.degrees(np.arccos(np.clip(-sign * normals[:, k], -1.0, 1.0))) if len(normals) else np.zeros(0)
        near = lean <= LEAN
        if not near.any():
            scores[up], leans[up] = -np.inf, np.nan
            continue
        face = TIP * np.minimum(tipping[near], TIP_CAP) / 30.0 - LEANING * lean[near] / 30.0
        best = int(np.argmax(face))
        footprint = max(extent[j] for j in range(3) if j != k)
        flatness = np.log(max(extent[k], 1e-12 * footprint) / footprint) if footprint > 0 else 0.0
        score = face[best] - FLAT * max(0.0, FLAT_BELOW - flatness)
        if across == k:
            score -= ACROSS_MIRROR
        if up == "z":
            score += Z_CONVENTION
        scores[up], leans[up] = float(score), float(lean[near][best])
    return scores, leans


def find_upright(mesh: Mesh, path: str = "") -> Upright:
    """The up axis `mesh` (as stored in the file `path`) stands on."""
    if str(path).lower().endswith(Y_UP_BY_SPEC):
        return Upright("y", {}, "glTF is +Y up")
    scores, leans = axis_scores(mesh.vertices, mesh.faces)
    best = max(AXES, key=lambda up: scores[up])
    if scores[best] < STANDS:
        return Upright("y", scores, "+Y up, as stored (no side stands clearly)")
    if scores["y"] > -np.inf and leans["y"] <= SQUARE and scores[best] - scores["y"] < KEEP:
        return Upright("y", scores, "+Y up, as stored")
    why = "it would topple with +Y up" if scores["y"] == -np.inf else "it stands better than with +Y up"
    return Upright(best, scores, f"stood up: {axis_name(best)} up, {why}")


def turned(mesh: Mesh, up: str) -> Mesh:
    """The mesh with its stored axis `up` turned to +Y."""
    if up == "y":
        return mesh
    vertices = mesh.vertices @ rotation_to_y_up(up).T
    return Mesh(vertices=vertices, faces=mesh.faces, normals=vertex_normals(vertices, mesh.faces), uvs=mesh.uvs,
                colors=mesh.colors, material=mesh.material, source=mesh.source)
