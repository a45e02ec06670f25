"""Which bones may carry each piece of a multi-part mesh (a robot's separate head, limbs and bolts).

A skeleton that stands where the artist put it runs through the pieces it drives: the head bone lies
inside the head, the forearm inside the forearm. A bone that merely passes near a piece (a hand raised
beside the head in the bind pose) must not carry it, or the piece follows the hand. So a piece is carried
only by the bones that run through it. A piece no bone runs through (a bolt, a thumb, a thin plate) is a
part fixed to the piece it touches: it takes that piece's bones.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..graph.graph import DeformationGraph
from ..graph.pieces import ride_on
from ..mesh.mesh import Mesh
from .models import Skeleton

ALONG = 9  # points along a bone tested for lying inside a piece
THROUGH = 2  # of them inside, for the bone to run through the piece
SHARE = 0.5  # and at least this share of the most any bone has inside the piece
MIN_NODES = 8  # without the mesh, a piece needs this many nodes for an inside test (fewer: any bone)


def piece_bones(graph: DeformationGraph, skeleton: Skeleton, joint_mask: np.ndarray,
                mesh: Mesh | None = None) -> np.ndarray | None:
    """(pieces, B) bool: per piece of the graph (`graph.pieces`) the rows of model.bones that may carry it,
    or None when the graph is one piece (every bone may carry every node) or no bone runs through any piece.

    With `mesh` (the graph's mesh, in the same frame) a point lies inside a piece when the piece's own
    triangles wind round it (generalized winding number ≥ 1/2), and a piece no bone runs through takes the
    bones of the piece it touches (`MeshPieces.contact_hosts`). Without it, a point lies inside when it is behind
    the normal of the piece's nearest node and within the piece's extent, and a piece no bone runs through may
    take any bone."""
    pieces = graph.pieces
    if pieces is None or len(pieces) != graph.node_count or len(np.unique(pieces)) < 2:
        return None
    bones = np.asarray(skeleton.model.bones, dtype=np.int64).reshape(-1, 2)
    pos = skeleton.positions
    use = joint_mask & skeleton.tracked
    ok = use[bones[:, 0]] & use[bones[:, 1]] & (np.linalg.norm(pos[bones[:, 1]] - pos[bones[:, 0]], axis=1) > 1e-9)
    ok &= skeleton.model.skinning_bones
    s = (np.arange(ALONG) + 0.5) / ALONG
    points = pos[bones[:, 0], None] + s[None, :, None] * (pos[bones[:, 1]] - pos[bones[:, 0]])[:, None]  # (B, A, 3)
    points = points.reshape(-1, 3)
    if mesh is not None:
        solid = mesh.pieces  # computed once per mesh, with its inside and contact tests
        count = max(solid.count, int(pieces.max()) + 1)
        inside = np.zeros((count, len(points)), bool)
        inside[:solid.count] = solid.inside(points)
    else:
        solid, count = None, int(pieces.max()) + 1
        inside = _inside_nodes(points, graph, pieces, count)
    # a bone that only crosses a piece (a neighbouring leg swung across it in the bind pose) runs a short
    # chord of it, the piece's own bone most of its length
    inside_count = np.where(ok[None], inside.reshape(count, len(bones), ALONG).sum(axis=2), 0)
    through = inside_count >= np.maximum(THROUGH, SHARE * inside_count.max(axis=1, keepdims=True))
    has = through.any(axis=1)
    if not has.any():
        return None
    if solid is not None:
        host = solid.contact_hosts(~has)
        for p in np.flatnonzero(~has):
            h = ride_on(host, p, has)
            through[p] = through[h] if h >= 0 else ok
    else:
        # riding on the nearest other node's piece would follow whatever touches it in the bind pose
        through[~has] = ok
    return through


def _inside_nodes(points: np.ndarray, graph: DeformationGraph, pieces: np.ndarray, count: int) -> np.ndarray:
    """(pieces, P) bool: each point behind the normal of the piece's nearest node and within its extent, for
    pieces with at least MIN_NODES nodes."""
    out = np.zeros((count, len(points)), bool)
    for p in range(count):
        mine = np.flatnonzero(pieces == p)
        if len(mine) < MIN_NODES:
            continue
        nodes, normals = graph.nodes[mine], graph.normals[mine]
        dist, near = cKDTree(nodes).query(points)
        behind = np.einsum("ni,ni->n", points - nodes[near], normals[near]) < 0.0
        out[p] = behind & (dist < 0.5 * float(np.ptp(nodes, axis=0).max()))
    return out
