"""Eq. 2 weights: 4 per vertex, normalised, glTF-ready, and orientation-aware on thin parts."""
import numpy as np
import trimesh

import kinetre
from kinetre.mesh.load import mesh_from_trimesh


def test_weights_shape_dtype_and_sum(data_dir):
    m = kinetre.load_mesh(data_dir / "meshes" / "armadillo.obj")
    g = kinetre.build_graph(m, nodes=128)
    assert g.vertex_nodes.shape == (len(m.vertices), 4) and g.vertex_nodes.dtype == np.int32
    assert g.vertex_weights.dtype == np.float32 and g.vertex_weights.min() >= 0
    assert np.allclose(g.vertex_weights.sum(axis=1), 1.0, atol=1e-6)
    assert g.vertex_nodes.min() >= 0 and g.vertex_nodes.max() < g.node_count


def test_weights_fall_off_with_distance(data_dir):
    m = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    g = kinetre.build_graph(m, nodes=128)
    w = g.vertex_weights
    assert np.all(np.diff(w, axis=1) <= 1e-6)  # ranked nearest first, linear falloff


def test_vertex_at_node_is_dominated_by_it(data_dir):
    m = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    g = kinetre.build_graph(m, nodes=128)
    near = np.argmin(np.linalg.norm(m.vertices[:, None] - g.nodes[None, :20], axis=2), axis=0)
    assert np.all(g.vertex_nodes[near, 0] == np.arange(20))


def test_chair_leg_not_pulled_by_neighbouring_leg():
    # two thin legs 2 cm apart: the inner faces face each other
    legs = []
    for x in (-0.03, 0.03):
        box = trimesh.creation.box([0.04, 0.6, 0.04])
        v, f = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=0.01)
        legs.append(trimesh.Trimesh(v + [x, 0, 0], f))
    m = mesh_from_trimesh(trimesh.util.concatenate(legs))
    g = kinetre.build_graph(m, nodes=120, seed=0)
    side = np.sign(m.vertices[:, 0])
    node_side = np.sign(g.nodes[:, 0])
    w = g.vertex_weights
    # the inner faces, which face the other leg across the gap (coplanar front faces are genuinely
    # one surface at this node spacing)
    inner = (m.normals[:, 0] * -side > 0.99)
    assert inner.sum() > 100
    cross = (node_side[g.vertex_nodes] != side[:, None]) & (w > 0) & inner[:, None]
    assert cross.sum() == 0, f"{cross.sum()} weights pull a vertex from the other leg"
    # Euclidean ranking would pull the inner faces across the 2 cm gap
    d = np.linalg.norm(m.vertices[:, None] - g.nodes[None], axis=2)
    eu = np.argsort(d, axis=1)[:, :4]
    assert (node_side[eu] != side[:, None])[inner].any()


def test_weights_added_later_in_a_thread_are_the_same(data_dir):
    # `kinetre animate` builds the graph without weights and weighs it in a thread beside the solve
    from concurrent.futures import ThreadPoolExecutor

    from kinetre.graph.build import with_weights
    m = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    whole = kinetre.build_graph(m, nodes=128)
    bare = kinetre.build_graph(m, nodes=128, weights=False)
    assert bare.vertex_nodes.shape == (0, 4) and bare.vertex_weights.shape == (0, 4)
    assert np.array_equal(bare.nodes, whole.nodes) and np.array_equal(bare.edges, whole.edges)
    with ThreadPoolExecutor(2) as pool:
        later = [f.result() for f in [pool.submit(with_weights, bare, m) for _ in range(2)]]
    for g in later:
        assert np.array_equal(g.vertex_nodes, whole.vertex_nodes)
        assert np.array_equal(g.vertex_weights, whole.vertex_weights)
