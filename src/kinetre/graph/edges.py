"""Graph edges (KinÊtre paper, "Extending Embedded Deformation", Fig. 3-4): k-nearest neighbours
under D, joined by an MST, with bridge edges marked.

The edge list is the (E, 2) int32 form with edges[:, 0] < edges[:, 1], each undirected edge once.
"""
from __future__ import annotations

import networkx as nx
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree
from scipy.spatial.distance import cdist

from .distance import orientation_aware_distance


def knn_edges(positions: np.ndarray, normals: np.ndarray, k: int = 4) -> np.ndarray:
    """Undirected edges from each node to its k nearest others under D (finite D only).

    Returns
    -------
    (E, 2) int32, sorted rows, each edge once.
    """
    n = len(positions)
    pairs = []
    for start in range(0, n, 1024):
        stop = min(start + 1024, n)
        d = orientation_aware_distance(positions[start:stop, None], normals[start:stop, None],
                                       positions[None], normals[None])
        d[np.arange(stop - start), np.arange(start, stop)] = np.inf
        kk = min(k, n - 1)
        nearest = np.argpartition(d, kk - 1, axis=1)[:, :kk] if kk > 0 else np.zeros((stop - start, 0), int)
        rows = np.repeat(np.arange(start, stop), kk)
        cols = nearest.reshape(-1)
        finite = np.isfinite(d[rows - start, cols])
        pairs.append(np.stack([rows[finite], cols[finite]], axis=1))
    e = np.concatenate(pairs) if pairs else np.zeros((0, 2), int)
    e = np.sort(e, axis=1)
    return np.unique(e, axis=0).astype(np.int32).reshape(-1, 2)


def connect_components(positions: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Join the components of the graph by a minimum spanning tree over components.

    Components are weighted by the minimum Euclidean distance between their nodes; for every MST
    edge the closest node pair (s, t) becomes a graph edge.

    Returns
    -------
    edges : (E', 2) int32, the input edges plus the added ones
    added : (E',) bool, True for the MST-added edges
    """
    n = len(positions)
    adj = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    ncomp, label = connected_components(adj, directed=False)
    if ncomp == 1:
        return edges, np.zeros(len(edges), dtype=bool)
    members = [np.flatnonzero(label == c) for c in range(ncomp)]
    weight = np.zeros((ncomp, ncomp))
    closest = {}
    for a in range(ncomp):
        for b in range(a + 1, ncomp):
            d = cdist(positions[members[a]], positions[members[b]])
            i, j = np.unravel_index(np.argmin(d), d.shape)
            # a tiny floor keeps coincident components connected in the MST (0 means "no edge")
            weight[a, b] = max(d[i, j], 1e-300)
            closest[a, b] = (members[a][i], members[b][j])
    tree = minimum_spanning_tree(weight).tocoo()
    added = np.array([sorted(closest[min(a, b), max(a, b)]) for a, b in zip(tree.row, tree.col)],
                     dtype=np.int32).reshape(-1, 2)
    all_edges = np.concatenate([edges, added])
    flags = np.concatenate([np.zeros(len(edges), bool), np.ones(len(added), bool)])
    all_edges, first = np.unique(all_edges, axis=0, return_index=True)
    return all_edges.astype(np.int32), flags[first]


def bridge_edges(node_count: int, edges: np.ndarray) -> np.ndarray:
    """(E,) bool: graph-theoretic bridges and the edges that hang a part on a cut vertex.

    A cut vertex c splits the graph into parts when removed; the largest part is the body, and the
    edges from c into every other part get the rigidity term so that part cannot swing about c
    (paper Fig. 4 d–f).
    """
    g = nx.Graph()
    g.add_nodes_from(range(node_count))
    g.add_edges_from(map(tuple, edges))
    index = {tuple(e): i for i, e in enumerate(edges.tolist())}
    marked = np.zeros(len(edges), dtype=bool)
    for a, b in nx.bridges(g):
        marked[index[(min(a, b), max(a, b))]] = True
    for c in nx.articulation_points(g):
        rest = g.subgraph([v for v in g if v != c])
        parts = sorted(nx.connected_components(rest), key=len, reverse=True)
        for part in parts[1:]:
            for v in g.neighbors(c):
                if v in part:
                    marked[index[(min(c, v), max(c, v))]] = True
    return marked
