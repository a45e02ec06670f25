"""Graph edges (KinÊtre paper, "Extending Embedded Deformation", Fig. 3-4): k-nearest neighbours
under D, joined by an MST, with bridge edges marked.

The edge list is the (E, 2) int32 form with edges[:, 0] < edges[:, 1], each undirected edge once.
"""
from __future__ import annotations

from bisect import bisect_right

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

    A cut vertex c splits the graph into parts when removed; the largest part is the body (of equal ones,
    the one with the lowest node), and the edges from c into every other part get the rigidity term so
    that part cannot swing about c (paper Fig. 4 d–f). The graph's other components count as parts too.

    One depth-first search (Tarjan's low links) finds the bridges, the cut vertices and the parts, so the
    cost grows with the edge count, however many cut vertices a thin mesh's graph has.
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    marked = np.zeros(len(edges), dtype=bool)
    if len(edges) == 0:
        return marked
    s = _Search(node_count, edges)
    marked[s.bridges] = True
    # the largest two components (size, -lowest node): a cut vertex's own component is never its body
    comps = sorted(((s.size[r], -r) for r in s.roots), reverse=True)
    for c in s.cuts:
        root = s.root[c]
        parts = [(s.size[w], -s.low_node[w], w) for w in s.split[c]]  # the subtrees hanging on c alone
        if c != root:  # the rest: c's ancestors and what joins them, holding the root, the lowest node
            parts.append((s.size[root] - 1 - sum(p[0] for p in parts), -root, root))
        other = next((comp for comp in comps if comp[1] != -root), None)
        if other is not None:
            parts.append((other[0], other[1], -1))
        body = max(parts)[2]
        for slot in range(s.start[c], s.start[c + 1]):
            if s.part_of(c, s.neighbour[slot]) != body:
                marked[s.edge_id[slot]] = True
    return marked


class _Search:
    """An iterative depth-first search of an undirected simple graph (a long chain of nodes must not exhaust
    Python's stack): discovery order, low links, subtree sizes and lowest nodes, the bridges (edge indices),
    the cut vertices and, per cut vertex, the children whose subtrees only it joins to the rest."""

    def __init__(self, node_count: int, edges: np.ndarray):
        ends = np.concatenate([edges[:, 0], edges[:, 1]])
        order = np.argsort(ends, kind="stable")
        self.start = np.searchsorted(ends[order], np.arange(node_count + 1)).tolist()
        self.neighbour = np.concatenate([edges[:, 1], edges[:, 0]])[order].tolist()
        self.edge_id = np.tile(np.arange(len(edges)), 2)[order].tolist()
        n, start, neighbour, edge_id = node_count, self.start, self.neighbour, self.edge_id
        seen, low = [-1] * n, [0] * n
        self.seen, self.size, self.low_node, self.root = seen, [1] * n, list(range(n)), [0] * n
        self.children: list[list[int]] = [[] for _ in range(n)]
        self.split: dict[int, list[int]] = {}
        self.bridges: list[int] = []
        self.roots: list[int] = []
        clock = 0
        for root in range(n):
            if seen[root] >= 0:
                continue
            self.roots.append(root)
            seen[root] = low[root] = clock
            clock += 1
            self.root[root] = root
            stack = [(root, -1, start[root])]  # (node, the tree edge it was reached by, next adjacency slot)
            while stack:
                v, via, slot = stack[-1]
                if slot < start[v + 1]:
                    stack[-1] = (v, via, slot + 1)
                    w, e = neighbour[slot], edge_id[slot]
                    if e == via:
                        continue
                    if seen[w] < 0:
                        seen[w] = low[w] = clock
                        clock += 1
                        self.root[w] = root
                        self.children[v].append(w)
                        stack.append((w, e, start[w]))
                    elif seen[w] < low[v]:
                        low[v] = seen[w]
                    continue
                stack.pop()
                if not stack:
                    break
                parent = stack[-1][0]
                low[parent] = min(low[parent], low[v])
                self.size[parent] += self.size[v]
                self.low_node[parent] = min(self.low_node[parent], self.low_node[v])
                if low[v] > seen[parent]:
                    self.bridges.append(via)
                if low[v] >= seen[parent]:
                    self.split.setdefault(parent, []).append(v)
        # the root is a cut vertex when it has two subtrees; any other node when one subtree hangs on it alone
        self.cuts = sorted(c for c, hanging in self.split.items() if c != self.root[c] or len(hanging) > 1)

    def part_of(self, c: int, v: int) -> int:
        """The part of the graph without cut vertex c that its neighbour v lies in: the child of c whose
        subtree only c joins to the rest, or c's component's root for the rest."""
        seen = self.seen
        if seen[c] < seen[v] < seen[c] + self.size[c]:  # a descendant: in the subtree of one child of c
            kids = self.children[c]
            w = kids[bisect_right([seen[k] for k in kids], seen[v]) - 1]
            if w in self.split[c]:
                return w
        return self.root[c]
