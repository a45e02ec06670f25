"""A source that already stands inside the mesh (a rigged file's own animation driving its own body, posed
and saved as a plain mesh) is used where it stands: no scaling to a height, no turn, no search.

It is told geometrically, from the bind frame alone: the skeleton's joints (nearly all) lie within the
mesh's bounding box, the skeleton spans most of the mesh's longest side, and nearly every point along its
bones lies inside the surface (behind the nearest vertex's normal, else by its winding number where parts
overlap) or on it; joints that move no skin (a root on the floor, a socket) are not judged. A person's
skeleton from another character, however close in size, misses in a few places (a hand beside the hip, a
head above the head).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..mesh.mesh import Mesh
from ..mesh.solid import winding_numbers
from .align import NOMINAL, bone_points, inside_surface
from .fit import Placement
from .take import Take

SPAN = 0.5  # the skeleton's longest side is at least this share of the mesh's
SLACK = 0.05  # share of the mesh's longest side a joint may stand outside the box or a bone point off the surface
INSIDE = 0.9  # share of the bone points inside or on the surface
SAMPLE = 20000  # mesh vertices the inside test looks at, at most
WINDING_FACES = 200_000  # at most this many triangles for the winding-number check of a close call


def stands_inside(take: Take, mesh: Mesh, bind_frame: int = 0) -> bool:
    """Whether `take`'s bind frame lies inside `mesh` as it stands (same units and frame)."""
    frame = take.frame(bind_frame)
    # a joint that moves no skin (a root on the floor, a socket where props attach) need not lie inside:
    # only the skin's joints and the bones they turn are judged
    still = set(take.model.unskinned)
    skinned = np.array([j not in still for j in take.model.joints], dtype=bool)
    joints = frame.positions[frame.tracked & skinned]
    if len(joints) < 2 or len(mesh.vertices) < 4:
        return False
    lo, hi = mesh.bounds
    longest = float(np.max(hi - lo))
    if not longest > 0:
        return False
    slack = SLACK * longest
    # nearly every joint within the box (a rig's helpers, an IK pole target, may stand outside the body)
    if ((joints < lo - slack) | (joints > hi + slack)).any(axis=1).mean() > 1.0 - INSIDE:
        return False
    if float(np.max(np.ptp(joints, axis=0))) < SPAN * longest:
        return False
    bones = np.asarray(take.model.bones).reshape(-1, 2)
    bones = bones[skinned[bones[:, 0]] & skinned[bones[:, 1]]]
    if not len(bones):
        return False
    points = bone_points(frame.positions, frame.tracked, bones)
    # some tens of thousands of vertices tell inside from outside as well as millions
    some = np.random.default_rng(0).permutation(len(mesh.vertices))[:SAMPLE]
    vertices, normals = mesh.vertices[some], mesh.normals[some]
    tree = cKDTree(vertices)
    near, _ = tree.query(points)
    ok = inside_surface(points, tree, vertices, normals) | (near < slack)
    if INSIDE > float(ok.mean()) >= 0.5 and len(mesh.faces) <= WINDING_FACES:
        # parts that overlap (a game character's limbs pushed into its body) put vertices inside the
        # body whose normals face away: the winding number tells inside from outside for those points
        ok[~ok] = winding_numbers(points[~ok], mesh.vertices, mesh.faces) > 0.5
    return float(ok.mean()) >= INSIDE


def in_place(mesh: Mesh) -> Placement:
    """The placement that leaves a source where it stands: mesh and skeleton scaled alike so the mesh's
    longest side is `NOMINAL` metres in the solve frame (attachment's reach is sized for people), no turn."""
    lo, hi = mesh.bounds
    k = NOMINAL / float(np.max(hi - lo))
    return Placement(k, np.eye(3), np.zeros(3), 1.0 / k, skeleton_scale=k, method="in place")
