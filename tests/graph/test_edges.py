"""Graph edges: k-NN under D, one connected graph always, bridges and cut-vertex edges marked."""
import networkx as nx
import numpy as np
import trimesh

import kinetre
from kinetre.graph.edges import bridge_edges, connect_components, knn_edges
from kinetre.mesh.load import mesh_from_trimesh


def _connected(n, edges):
    g = nx.Graph()
    g.add_nodes_from(range(n))
    g.add_edges_from(map(tuple, edges))
    return nx.is_connected(g)


def test_knn_edges_are_undirected_unique_and_finite():
    rng = np.random.default_rng(0)
    pos = rng.random((80, 3))
    nrm = np.tile([0.0, 0.0, 1.0], (80, 1))
    e = knn_edges(pos, nrm, 4)
    assert e.dtype == np.int32 and np.all(e[:, 0] < e[:, 1])
    assert len(np.unique(e, axis=0)) == len(e)
    deg = np.bincount(e.reshape(-1), minlength=80)
    assert deg.min() >= 4  # every node keeps its own 4 nearest


def test_opposite_normals_are_never_neighbours():
    pos = np.array([[0, 0, 0], [0.01, 0, 0], [1, 0, 0], [1.01, 0, 0]], float)
    nrm = np.array([[0, 0, 1], [0, 0, -1], [0, 0, 1], [0, 0, -1]], float)
    e = knn_edges(pos, nrm, 4)
    assert {tuple(x) for x in e.tolist()} == {(0, 2), (1, 3)}


def test_components_joined_by_mst_edges_marked_as_bridges():
    pos = np.array([[0, 0, 0], [1, 0, 0], [10, 0, 0], [11, 0, 0], [30, 0, 0], [31, 0, 0]], float)
    edges = np.array([[0, 1], [2, 3], [4, 5]], np.int32)
    all_edges, added = connect_components(pos, edges)
    assert _connected(6, all_edges)
    assert {tuple(x) for x in all_edges[added].tolist()} == {(1, 2), (3, 4)}  # closest pairs


def test_cut_vertex_edges_are_marked():
    # two triangles sharing vertex 2 (a bowtie) plus a pendant path: 2 is a cut vertex
    edges = np.array([[0, 1], [0, 2], [1, 2], [2, 3], [2, 4], [3, 4], [3, 5], [4, 5], [5, 6], [6, 7],
                      [5, 7]], np.int32)
    marked = bridge_edges(8, edges)
    # body = {3..7} (largest part when 2 is removed); {0, 1} hangs on 2 by edges (0,2), (1,2)
    m = {tuple(e) for e in edges[marked].tolist()}
    assert (0, 2) in m and (1, 2) in m
    assert (3, 4) not in m and (6, 7) not in m


def test_true_bridge_is_marked():
    edges = np.array([[0, 1], [1, 2], [0, 2], [2, 3], [3, 4], [4, 5], [3, 5]], np.int32)
    marked = bridge_edges(6, edges)
    assert marked[3]  # (2, 3) is a bridge


def test_build_graph_always_connected_on_disjoint_parts():
    parts = [trimesh.creation.box([0.2, 1, 0.2]).apply_translation([x, 0, 0]) for x in (0, 1, 2.5)]
    m = mesh_from_trimesh(trimesh.util.concatenate(parts))
    g = kinetre.build_graph(m, nodes=90, seed=0)
    assert _connected(g.node_count, g.edges)
    assert g.bridges.sum() >= 2


def _networkx_marks(n, edges):
    """The rule of `bridge_edges` as networkx computes it: bridges, then per cut vertex every part of the
    graph without it but the largest (the first found of equal ones)."""
    g = nx.Graph()
    g.add_nodes_from(range(n))
    g.add_edges_from(map(tuple, edges.tolist()))
    index = {tuple(e): i for i, e in enumerate(edges.tolist())}
    marked = np.zeros(len(edges), dtype=bool)
    for a, b in nx.bridges(g):
        marked[index[(min(a, b), max(a, b))]] = True
    for c in nx.articulation_points(g):
        parts = sorted(nx.connected_components(g.subgraph([v for v in g if v != c])), key=len, reverse=True)
        for part in parts[1:]:
            for v in g.neighbors(c):
                if v in part:
                    marked[index[(min(c, v), max(c, v))]] = True
    return marked


def test_marks_match_networkx_on_random_sparse_graphs():
    # trees, chains, cycles with pendants, several components, equal-sized parts: the cases cut vertices make
    rng = np.random.default_rng(3)
    cases = 0
    for trial in range(300):
        n = int(rng.integers(2, 40))
        m = int(rng.integers(0, 2 * n))
        pairs = rng.integers(0, n, size=(m, 2))
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        if trial % 3 == 0:  # a path through every node, so long chains and deep searches occur
            pairs = np.concatenate([pairs, np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)])
        edges = np.unique(np.sort(pairs, axis=1), axis=0).astype(np.int32).reshape(-1, 2)
        want = _networkx_marks(n, edges)
        np.testing.assert_array_equal(bridge_edges(n, edges), want, err_msg=f"trial {trial}: {edges.tolist()}")
        cases += bool(want.any())
    assert cases > 100


def test_a_long_chain_does_not_exhaust_the_stack():
    n = 20000
    edges = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int32)
    assert bridge_edges(n, edges).all()
