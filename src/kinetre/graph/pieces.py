"""A mesh in several pieces (a robot's separate limbs, a truck's wheels): which piece each vertex and each
graph node lies on, and skinning kept to a vertex's own piece so a piece never blends in the motion of
the piece beside it (which shears both where they touch).
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree


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


def node_pieces(vertices: np.ndarray, pieces: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(N,) int32: per graph node (a point on the surface) the piece of its nearest vertex."""
    _, nearest = cKDTree(vertices).query(nodes)
    return np.asarray(pieces, dtype=np.int32)[nearest]


def keep_to_pieces(indices: np.ndarray, weights: np.ndarray, vertices: np.ndarray, pieces: np.ndarray,
                   nodes: np.ndarray, node_piece: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Skinning (V, 4) `indices` / `weights` with every vertex's nodes kept to its own piece.

    A vertex's weights on nodes of other pieces go and the rest are scaled back to a sum of 1; a vertex
    left with none takes its piece's nearest node alone. A piece with no node of its own (a small part, a
    bolt) is kept to one host instead: the piece of the node nearest to most of its vertices, so it rides
    on one part rather than between two.
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
        for p in np.unique(pieces[orphans]):
            host[p] = np.bincount(node_piece[nearest[pieces[orphans] == p]]).argmax()
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
