"""A mesh in several pieces (a robot's separate limbs, a truck's wheels): which piece each vertex and each
graph node lies on, and skinning kept to a vertex's own piece so a piece never blends in the motion of
the piece beside it (which shears both where they touch).
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..mesh.solid import surface_distances

CONTACT = 0.5  # a piece touches another when the gap is within this fraction of its own size
MOST_POINTS = 256  # of a piece's vertices measured for its gap to the others


def vertex_pieces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V,) int32: the connected component (through faces) of every vertex, numbered from 0. Vertices at one
    place count as one (a UV or normal seam splits a surface's vertices, not the surface)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    if len(vertices) == 0:
        return np.zeros(0, np.int32)
    size = float(np.ptp(vertices, axis=0).max()) or 1.0
    _, weld = np.unique(np.round((vertices - vertices.min(axis=0)) / (1e-7 * size)).astype(np.int64), axis=0,
                        return_inverse=True)
    weld = weld.reshape(-1)
    f = weld[np.asarray(faces, dtype=np.int64).reshape(-1, 3)]
    places = int(weld.max()) + 1
    rows = f.ravel()
    cols = np.roll(f, 1, axis=1).ravel()
    adj = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(places, places))
    labels = connected_components(adj, directed=False)[1][weld]
    return np.unique(labels, return_inverse=True)[1].reshape(-1).astype(np.int32)


def contact_hosts(vertices: np.ndarray, faces: np.ndarray, pieces: np.ndarray, which: np.ndarray) -> np.ndarray:
    """(pieces,) int: for every piece in `which` (bool per piece) the other piece whose surface comes closest
    to it (the plate a bolt is screwed to, the hand a thumb is part of), -1 for none within CONTACT of the
    piece's own size (it floats) and for the pieces not asked about.

    The gap is measured from the piece's vertices to the other pieces' triangles, so a part beside another
    in the bind pose (a thumb raised next to the head) loses to the one it is fixed to."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    pieces = np.asarray(pieces)
    host = np.full(len(which), -1)
    face_piece = pieces[faces[:, 0]]
    boxes = {q: (vertices[pieces == q].min(axis=0), vertices[pieces == q].max(axis=0)) for q in np.unique(pieces)}
    for p in np.flatnonzero(which):
        if p not in boxes:
            continue
        lo, hi = boxes[p]
        size = float((hi - lo).max())
        mine = np.flatnonzero(pieces == p)
        mine = mine[np.linspace(0, len(mine) - 1, min(len(mine), MOST_POINTS)).astype(np.int64)]
        reach_lo, reach_hi = lo - CONTACT * size, hi + CONTACT * size
        best, gap = -1, CONTACT * size
        for q, (qlo, qhi) in boxes.items():
            if q == p or (qlo > reach_hi).any() or (qhi < reach_lo).any():
                continue
            tri = faces[face_piece == q]
            corners = vertices[tri]
            close = ((corners.min(axis=1) <= reach_hi) & (corners.max(axis=1) >= reach_lo)).all(axis=1)
            if not close.any():
                continue
            d = float(surface_distances(vertices[mine], vertices, tri[close]).min())
            if d <= gap:
                best, gap = int(q), d
        host[p] = best
    return host


def ride_on(host: np.ndarray, piece: int, settled: np.ndarray) -> int:
    """The piece `piece` rides on: its `host` (`contact_hosts`), that one's host while it is not `settled`
    (bool per piece: a bolt on a plate on an arm rides the arm), or -1 when the chain ends or loops first."""
    h, seen = int(host[piece]), {piece}
    while h >= 0 and not settled[h] and h not in seen:
        seen.add(h)
        h = int(host[h])
    return h if h >= 0 and settled[h] else -1


def node_pieces(vertices: np.ndarray, pieces: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(N,) int32: per graph node (a point on the surface) the piece of its nearest vertex."""
    _, nearest = cKDTree(vertices).query(nodes)
    return np.asarray(pieces, dtype=np.int32)[nearest]


def keep_to_pieces(indices: np.ndarray, weights: np.ndarray, vertices: np.ndarray, pieces: np.ndarray,
                   nodes: np.ndarray, node_piece: np.ndarray,
                   faces: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Skinning (V, 4) `indices` / `weights` with every vertex's nodes kept to its own piece.

    A vertex's weights on nodes of other pieces go and the rest are scaled back to a sum of 1; a vertex
    left with none takes its piece's nearest node alone. A piece with no node of its own (a small part, a
    bolt) is kept to one host instead, so it rides on one part rather than between two: with `faces` the
    piece it touches (`contact_hosts`, followed on to one with nodes), else or failing that the piece of the
    node nearest to most of its vertices.
    """
    idx = np.asarray(indices).copy()
    w = np.asarray(weights, dtype=np.float32).copy()
    if len(idx) == 0 or len(np.unique(node_piece)) < 2:
        return idx, w
    has_nodes = np.zeros(int(max(pieces.max(), node_piece.max())) + 1, bool)
    has_nodes[node_piece] = True
    host = np.arange(len(has_nodes))
    orphans = np.flatnonzero(~has_nodes[pieces])
    if len(orphans):
        _, nearest = cKDTree(nodes).query(vertices[orphans])
        touching = contact_hosts(vertices, faces, pieces, ~has_nodes) if faces is not None else None
        for p in np.unique(pieces[orphans]):
            host[p] = np.bincount(node_piece[nearest[pieces[orphans] == p]]).argmax()
            h = ride_on(touching, p, has_nodes) if touching is not None else -1
            if h >= 0:
                host[p] = h
    pieces = host[pieces]
    kept = np.where(node_piece[idx] == pieces[:, None], w, 0.0).astype(np.float32)
    total = kept.sum(axis=1)
    fine = total > 1e-6
    w[fine] = kept[fine] / total[fine, None]
    alone = np.flatnonzero(~fine)
    for p in np.unique(pieces[alone]):
        vs = alone[pieces[alone] == p]
        mine = np.flatnonzero(node_piece == p)
        _, k = cKDTree(nodes[mine]).query(vertices[vs])
        idx[vs] = mine[k][:, None]
        w[vs] = [1.0, 0.0, 0.0, 0.0]
    # heaviest first again, as the ranking left them (a dropped node leaves a gap)
    order = np.argsort(-w, axis=1, kind="stable")
    return np.take_along_axis(idx, order, axis=1), np.take_along_axis(w, order, axis=1)
