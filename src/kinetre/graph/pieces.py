"""A mesh in several pieces (a robot's separate limbs, a truck's wheels): which piece each vertex and each
graph node lies on, and skinning kept to a vertex's own piece so a piece never blends in the motion of
the piece beside it (which shears both where they touch).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..mesh.pieces import MeshPieces, connected_pieces


def vertex_pieces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V,) int32: the connected component (through faces) of every vertex, numbered by first vertex
    (`mesh.pieces.connected_pieces`; a mesh keeps its own as `Mesh.pieces.of_vertex`)."""
    return connected_pieces(vertices, faces)[0]


def ride_on(host: np.ndarray, piece: int, settled: np.ndarray) -> int:
    """The piece `piece` rides on: its `host` (`MeshPieces.contact_hosts`), that one's host while it is not `settled`
    (bool per piece: a bolt on a plate on an arm rides the arm), or -1 when the chain ends or loops first."""
    h, seen = int(host[piece]), {piece}
    while h >= 0 and not settled[h] and h not in seen:
        seen.add(h)
        h = int(host[h])
    return h if h >= 0 and settled[h] else -1


def node_pieces(pieces: np.ndarray, faces: np.ndarray, node_faces: np.ndarray) -> np.ndarray:
    """(N,) int32: per graph node the piece of the triangle it was sampled on (`node_faces`, rows of `faces`),
    given every vertex's piece."""
    faces = np.asarray(faces).reshape(-1, 3)
    return np.asarray(pieces, dtype=np.int32)[faces[np.asarray(node_faces, dtype=np.int64), 0]]


def keep_to_pieces(indices: np.ndarray, weights: np.ndarray, vertices: np.ndarray, mesh_pieces: MeshPieces,
                   nodes: np.ndarray, node_piece: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Skinning (V, 4) `indices` / `weights` with every vertex's nodes kept to its own piece.

    A vertex's weights on nodes of other pieces go and the rest are scaled back to a sum of 1; a vertex
    left with none takes its piece's nearest node alone. A piece with no node of its own (a small part, a
    bolt) is kept to one host instead, so it rides on one part rather than between two: the piece it touches
    (`MeshPieces.contact_hosts`, followed on to one with nodes), failing that the piece of the node nearest to
    most of its vertices.
    """
    pieces = mesh_pieces.of_vertex
    if len(indices) == 0 or mesh_pieces.count < 2 or len(np.unique(node_piece)) < 2:
        return np.asarray(indices), np.asarray(weights, dtype=np.float32)
    idx = np.asarray(indices).copy()
    w = np.asarray(weights, dtype=np.float32).copy()
    has_nodes = np.zeros(int(max(pieces.max(), node_piece.max())) + 1, bool)
    has_nodes[node_piece] = True
    host = np.arange(len(has_nodes))
    orphans = np.flatnonzero(~has_nodes[pieces])
    if len(orphans):
        _, nearest = cKDTree(nodes).query(vertices[orphans])
        touching = mesh_pieces.contact_hosts(~has_nodes)
        for p in np.unique(pieces[orphans]):
            host[p] = np.bincount(node_piece[nearest[pieces[orphans] == p]]).argmax()
            h = ride_on(touching, p, has_nodes)
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
