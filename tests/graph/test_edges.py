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
