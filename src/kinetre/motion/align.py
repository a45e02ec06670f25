"""Place any skeleton in any mesh from the two shapes (patent claim 5: a horse walked by a quadruped).

`fit.fit_take` places humans (face +Z, scale to height). A skeleton of another kind (a fox, a horse, two
people joined by a joint map) is placed from the shapes instead, both taken +Y up (glTF, BVH and Kinetre
meshes are):

1. the long horizontal axis of each shape: principal axis (in x/z) of the source's bind-pose bones
   (points along every bone) and of the mesh's surface (area-weighted face centroids);
2. the source's front along its axis: the way it travels over the clip when it travels, else the end
   nearer a joint named "head", else its higher end; the mesh's front is the end of its axis that puts the
   source's bones inside the mesh best and matches the two height profiles (max height along the axis);
3. scale: mesh/source ratio of heights and of lengths (the middle 90 % of each, so a fox's tail does not
   count as body), their geometric mean by default (`fit="height"` or `"length"` takes one);
4. a small search over both horizontal axes of the mesh, scale (0.6-1.6x), position along the axis and height maximises the share of bone
   points inside the mesh (inside: behind the nearest vertex's normal) plus the share of the mesh within
   `COVER` of a bone (so the legs reach into the legs, and a tiny skeleton deep inside does not win) plus
   how well the two ground contacts (the mesh's lowest 5 %, the source's lowest 10 %, in x/z) overlap, from
   the grounded, centred start.

The solve frame is the mesh scaled to `NOMINAL` metres on its longest side, so the 10 cm reach and 4 cm
bones of attachment (sized for people) mean the same on a mouse and on a whale. `ShapeFit.notes` says in
words when the match is poor and what to try (`--yaw`, `--flip`, `--fit height|length`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import BadMotionError
from ..mesh.mesh import Mesh
from .fit import Placement, yaw_rotation
from .take import Take

NOMINAL = 1.7  # metres: the longest side of the mesh in the solve frame (a person's height)
JOINT_REACH = 0.07  # metres in the solve frame: the median joint this near a graph node (attachment reach 0.1)
COVER = 0.2  # metres in the solve frame: a mesh vertex this near a bone point counts as covered
FITS = ("auto", "height", "length")


@dataclass(frozen=True)
class ShapeFit:
    """A placement from the shapes and what was decided on the way.

    Attributes
    ----------
    placement : Placement (with `skeleton_scale`: source units -> solve frame)
    front : str, how the source's front was found ("motion", "head joint", "profile")
    turn : float, degrees about +Y applied to the source (after any hint)
    ratios : (height, length) mesh/source size ratios in the solve frame at scale 1
    inside : float, share of the source's bone points inside the mesh after fitting
    notes : list of str, warnings in words (empty when the match looks good)
    """

    placement: Placement
    front: str
    turn: float
    ratios: tuple[float, float]
    inside: float
    notes: tuple[str, ...]


def bone_points(positions: np.ndarray, tracked: np.ndarray, bones: np.ndarray, per_bone: int = 6) -> np.ndarray:
    """(N, 3) the tracked joints plus `per_bone` evenly spaced points inside every tracked bone."""
    pts = [positions[tracked]]
    ok = tracked[bones[:, 0]] & tracked[bones[:, 1]]
    a, b = positions[bones[ok, 0]], positions[bones[ok, 1]]
    s = (np.arange(per_bone) + 1.0) / (per_bone + 1.0)
    pts.append((a[:, None] + s[None, :, None] * (b - a)[:, None]).reshape(-1, 3))
    return np.concatenate(pts)


def _axis(points: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """(3,) unit horizontal principal axis of the points' x/z spread."""
    xz = points[:, [0, 2]]
    w = np.ones(len(xz)) if weights is None else weights
    c = xz - np.average(xz, axis=0, weights=w)
    cov = (c * w[:, None]).T @ c / w.sum()
    vals, vecs = np.linalg.eigh(cov)
    v = vecs[:, -1]
    return np.array([v[0], 0.0, v[1]])


def _profile(points: np.ndarray, axis: np.ndarray, bins: int = 8) -> np.ndarray:
    """Highest point per slice along `axis` (heights scaled to 0..1, empty slices interpolated)."""
    s = points @ axis
    s = (s - s.min()) / max(np.ptp(s), 1e-12)
    y = points[:, 1]
    y = (y - y.min()) / max(np.ptp(y), 1e-12)
    k = np.minimum((s * bins).astype(int), bins - 1)
    top = np.full(bins, np.nan)
    for i in range(bins):
        if np.any(k == i):
            top[i] = y[k == i].max()
    good = np.isfinite(top)
    return np.interp(np.arange(bins), np.flatnonzero(good), top[good])


def source_front(take: Take, bind: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, str]:
    """The source's front along its axis and how it was found ("motion", "head joint" or "profile")."""
    pos = take.positions
    ok = take.tracked[0] & take.tracked[-1]
    length = max(float(np.ptp(bind @ axis)), 1e-9)
    if ok.any():
        travel = (pos[-1, ok] - pos[0, ok]).mean(axis=0)
        along = float(travel @ axis)
        if abs(along) > 0.25 * length:
            return axis * math.copysign(1.0, along), "motion"
    frame = take.frame(0)
    heads = [i for i, n in enumerate(take.model.joints) if "head" in n.lower() and frame.tracked[i]]
    if heads:
        centre = frame.positions[frame.tracked].mean(axis=0)
        along = float((frame.positions[heads].mean(axis=0) - centre) @ axis)
        if abs(along) > 0.05 * length:
            return axis * math.copysign(1.0, along), "head joint"
    prof = _profile(bind, axis)
    return (axis if prof[-2:].mean() >= prof[:2].mean() else -axis), "profile"


def _extent(values: np.ndarray) -> float:
    """Spread of the middle 90 % of the values (a thin tail or an antenna does not set a body's size)."""
    lo, hi = np.percentile(values, [5.0, 95.0])
    return float(hi - lo)


def inside_surface(points: np.ndarray, tree: cKDTree, vertices: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(N,) bool: each point lies behind the normal of its nearest mesh vertex (inside a closed surface)."""
    _, i = tree.query(points)
    return np.einsum("ni,ni->n", points - vertices[i], normals[i]) < 0


def fit_shapes(take: Take, mesh: Mesh, bind_frame: int = 0, fit: str = "auto", yaw: float = 0.0,
               flip: bool = False, fit_mesh: bool = False, nodes: np.ndarray | None = None) -> ShapeFit:
    """Place a non-human take in a mesh from the two shapes (module docstring).

    Parameters
    ----------
    take : Take, +Y up (any units)
    mesh : Mesh, +Y up (any units)
    bind_frame : the frame that is the bind pose
    fit : "auto" (geometric mean of the height and length ratios), "height" or "length"
    yaw : degrees about +Y added to the found facing; flip : turn the found facing by 180°
    fit_mesh : resize the mesh to the solve frame in the output instead of keeping its size
    nodes : (N, 3) the deformation graph's nodes (mesh units), if built: the solve frame is then shrunk
        until the median joint lies within `JOINT_REACH` of a node, so a thick body (a cow round a fox's
        skeleton) still catches the joints in its 10 cm attachment reach

    Raises
    ------
    BadMotionError
        The bind frame tracks fewer than two joints, or has no extent.
    """
    if fit not in FITS:
        raise BadMotionError(f"fit must be one of {', '.join(FITS)}, got {fit!r}")
    where = take.source or "take"
    frame = take.frame(bind_frame)
    if frame.tracked.sum() < 2:
        raise BadMotionError(f"{where}: bind frame {bind_frame} tracks {int(frame.tracked.sum())} joint(s), "
                             f"need at least 2")
    src = bone_points(frame.positions, frame.tracked, take.model.bones)
    if not np.ptp(src, axis=0).max() > 1e-9:
        raise BadMotionError(f"{where}: bind frame {bind_frame} has no extent and cannot be fitted")

    # the solve frame: the mesh with its longest side NOMINAL metres
    lo, hi = mesh.bounds
    k = NOMINAL / float((hi - lo).max())
    verts = mesh.vertices * k
    tri = verts[mesh.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    centroids = tri.mean(axis=1)
    mesh_axis = _axis(centroids, area + 1e-30) if area.sum() > 0 else _axis(verts)
    src_axis = _axis(src)
    front, how = source_front(take, src, src_axis)
    # a few thousand vertices tell inside from outside well enough and keep the search's queries cheap
    some = np.random.default_rng(0).permutation(len(verts))[:4000]
    normals = mesh.normals[some]
    tree = cKDTree(verts[some], balanced_tree=False)
    probe = verts[some[:600]]
    # ground contact: the mesh's lowest 5 % and the source's lowest 10 % (its feet), compared in x/z
    ground = probe[probe[:, 1] < verts[:, 1].min() + 0.05 * np.ptp(verts[:, 1])]
    ground = ground if len(ground) else verts[np.argsort(verts[:, 1])[:20]]
    ground = ground * [1.0, 0.0, 1.0]
    ground_tree = cKDTree(ground)
    feet = src[src[:, 1] < src[:, 1].min() + 0.1 * np.ptp(src[:, 1])] * [1.0, 0.0, 1.0]
    # the candidates move the source (x -> s R x + t); queries about the source map the other way instead,
    # so each tree is built once: distances there are 1/s of those in the solve frame
    src_tree, feet_tree = cKDTree(src), cKDTree(feet)

    def heading(target):  # yaw (degrees) taking the source front onto `target`
        return math.degrees(math.atan2(target[0], target[2]) - math.atan2(front[0], front[2]))

    def ratios(turn):
        r = yaw_rotation(turn)
        placed = src @ r.T
        ax = r @ front
        return (float(_extent(verts[:, 1]) / max(_extent(placed[:, 1]), 1e-12)),
                float(_extent(verts @ ax) / max(_extent(placed @ ax), 1e-12)))

    def start(turn, scale):  # grounded and centred
        placed = scale * src @ yaw_rotation(turn).T
        mid = 0.5 * (placed.min(axis=0) + placed.max(axis=0))
        centre = 0.5 * (verts.min(axis=0) + verts.max(axis=0))
        return np.array([centre[0] - mid[0], verts[:, 1].min() - placed[:, 1].min(), centre[2] - mid[2]])

    def search(turn):
        rh, rl = ratios(turn)
        base = {"height": rh, "length": rl}.get(fit, math.sqrt(rh * rl))
        r = yaw_rotation(turn)
        ax = r @ front
        best = (-1.0, base, start(turn, base))
        length = float(np.ptp(verts @ ax))
        height = float(np.ptp(verts[:, 1]))
        moves = np.array([(da, dy) for da in np.linspace(-0.15, 0.15, 7) for dy in np.linspace(0.0, 0.15, 4)])
        for m in (0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.25, 1.4, 1.6) if fit == "auto" else (1.0,):
            s = base * m
            t = start(turn, s) + moves[:, :1] * length * ax + moves[:, 1:] * [0.0, height, 0.0]  # (C, 3)
            placed = s * src @ r.T + t[:, None]                                                # (C, N, 3)
            inside = inside_surface(placed.reshape(-1, 3), tree, tree.data, normals).reshape(len(t), -1).mean(axis=1)
            back = ((probe[None] - t[:, None]) @ r) / s                     # the mesh probe in source units
            covered = np.isfinite(src_tree.query(back.reshape(-1, 3), distance_upper_bound=COVER / s)[0])
            ground_back = ((ground[None] - t[:, None] * [1.0, 0.0, 1.0]) @ r) / s
            reached = np.isfinite(feet_tree.query(ground_back.reshape(-1, 3), distance_upper_bound=COVER / s)[0])
            feet_placed = s * feet @ r.T + t[:, None] * [1.0, 0.0, 1.0]
            landed = np.isfinite(ground_tree.query(feet_placed.reshape(-1, 3), distance_upper_bound=COVER)[0])
            score = (inside + covered.reshape(len(t), -1).mean(axis=1)
                     + 0.5 * (reached.reshape(len(t), -1).mean(axis=1) + landed.reshape(len(t), -1).mean(axis=1)))
            # ties (and near-ties) go to the unmoved start: prefer the plain fit
            score -= 0.02 * (abs(m - 1.0) + np.abs(moves[:, 0]) + moves[:, 1])
            i = int(np.argmax(score))
            if score[i] > best[0]:
                best = (float(score[i]), s, t[i])
        return best, (rh, rl)

    candidates = []
    across = np.cross([0.0, 1.0, 0.0], mesh_axis)
    for axis in (mesh_axis, across):  # the long axes usually agree; a biped driven by a quadruped: across
        prof_m = _profile(verts, axis)
        for sign in (1.0, -1.0):
            turn = heading(sign * axis)
            (score, s, t), rs = search(turn)
            prof = _profile(src @ yaw_rotation(turn).T, yaw_rotation(turn) @ front)
            match = 1.0 - float(np.abs(prof - prof_m[::int(sign)]).mean())
            candidates.append((score + 0.25 * match, turn, s, t, rs, score))
    candidates.sort(key=lambda c: -c[0])
    best = candidates[0]
    other = next(c for c in candidates if abs((c[1] - best[1]) % 360.0 - 180.0) < 1.0)  # its front <-> back
    turn = best[1]
    notes = []
    if flip or (yaw or 0.0):
        turn = turn + (180.0 if flip else 0.0) + (yaw or 0.0)
        (score, s, t), rs = search(turn)
        chosen = (None, turn, s, t, rs, score)
    else:
        chosen = best
        if best[0] - other[0] < 0.05:
            notes.append("the mesh's front and back look alike to the fit: if the motion runs backwards, "
                         "try --flip")
    _, turn, s, t, (rh, rl), _ = chosen
    inside = float(inside_surface(s * src @ yaw_rotation(turn).T + t, tree, tree.data, normals).mean())
    if max(rh, rl) / min(rh, rl) > 2.0:  # proportions twice apart: a fox in a giraffe
        longer = "longer" if rl < rh else "taller"
        notes.append(f"the source is {max(rh, rl) / min(rh, rl):.1f}x {longer} for its size than the mesh: "
                     f"try --fit height or --fit length")
    if inside < 0.6:
        notes.append(f"only {100 * inside:.0f} % of the source's bones lie inside the mesh after fitting: "
                     f"try --yaw 90, --flip or --fit height|length")
    shrink = 1.0
    if nodes is not None and len(nodes):
        joints = s * frame.positions[frame.tracked] @ yaw_rotation(turn).T + t
        d, _ = cKDTree(np.asarray(nodes) * k).query(joints)
        shrink = float(np.clip(JOINT_REACH / max(float(np.median(d)), 1e-12), 0.3, 1.0))
    k, s, t = k * shrink, s * shrink, t * shrink
    placement = Placement(k, yaw_rotation(turn), t, 1.0 if fit_mesh else 1.0 / k, skeleton_scale=s, method="shapes")
    return ShapeFit(placement, how, float(turn % 360.0), (rh, rl), inside, tuple(notes))
