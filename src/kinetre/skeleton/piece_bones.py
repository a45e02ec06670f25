"""Which bones may carry each piece of a multi-part mesh (a robot's separate head, limbs and bolts).

A skeleton that stands where the artist put it runs through the pieces it drives: the head bone lies
inside the head, the forearm inside the forearm. A bone that merely passes near a piece (a hand raised
beside the head in the bind pose) must not carry it, or the piece follows the hand. So a piece is carried
only by the bones that run through it; a piece no bone runs through (a bolt, a thin plate, one too small
to tell) may take any bone, as a one-piece mesh does.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..graph.graph import DeformationGraph
from .models import Skeleton

ALONG = 9  # points along a bone tested for lying inside a piece
THROUGH = 2  # of them inside, for the bone to run through the piece
MIN_NODES = 8  # a piece needs this many nodes for an inside test (fewer: any bone)


def piece_bones(graph: DeformationGraph, skeleton: Skeleton, joint_mask: np.ndarray) -> np.ndarray | None:
    """(pieces, B) bool: per piece of the graph (`graph.pieces`) the rows of model.bones that may carry it,
    or None when the graph is one piece (every bone may carry every node) or no bone runs through any piece.

    A point lies inside a piece when it is behind the normal of the piece's nearest node (a closed
    surface's outward normals) and within the piece's own extent."""
    pieces = graph.pieces
    if pieces is None or len(pieces) != graph.node_count or len(np.unique(pieces)) < 2:
        return None
    bones = np.asarray(skeleton.model.bones, dtype=np.int64).reshape(-1, 2)
    pos = skeleton.positions
    use = joint_mask & skeleton.tracked
    ok = use[bones[:, 0]] & use[bones[:, 1]] & (np.linalg.norm(pos[bones[:, 1]] - pos[bones[:, 0]], axis=1) > 1e-9)
    s = (np.arange(ALONG) + 0.5) / ALONG
    points = pos[bones[:, 0], None] + s[None, :, None] * (pos[bones[:, 1]] - pos[bones[:, 0]])[:, None]  # (B, A, 3)
    count = int(pieces.max()) + 1
    through = np.zeros((count, len(bones)), bool)
    for p in range(count):
        mine = np.flatnonzero(pieces == p)
        if len(mine) < MIN_NODES:
            continue
        nodes, normals = graph.nodes[mine], graph.normals[mine]
        dist, near = cKDTree(nodes).query(points.reshape(-1, 3))
        behind = np.einsum("ni,ni->n", points.reshape(-1, 3) - nodes[near], normals[near]) < 0.0
        extent = float(np.ptp(nodes, axis=0).max())
        inside = (behind & (dist < 0.5 * extent)).reshape(len(bones), ALONG)
        through[p] = ok & (inside.sum(axis=1) >= THROUGH)
    has = through.any(axis=1)
    if not has.any():
        return None
    # a piece no bone runs through (a plate, a bolt, one with too few nodes to tell) may take any bone, as a
    # one-piece mesh does: riding on the nearest other piece would follow whatever touches it in the bind pose
    through[~has] = ok
    return through
