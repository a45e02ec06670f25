"""CPU skinning equals Eq. 2 evaluated directly, and the identity pose changes nothing; the float32
`SkinTable` agrees with the float64 path to 1e-5 of the mesh's size, row for row."""
import numpy as np
import pytest

import kinetre
from kinetre.deform.skinning import CHUNK, SkinTable, skin_vertices


def test_identity_pose_changes_nothing(body, body_graph):
    v = kinetre.skin(body, body_graph, kinetre.GraphPose.identity(body_graph.node_count))
    assert np.abs(v - body.vertices).max() < 1e-6


def test_matches_eq2_reference(body, body_graph):
    rng = np.random.default_rng(0)
    n = body_graph.node_count
    pose = kinetre.GraphPose(np.eye(3) + 0.2 * rng.standard_normal((n, 3, 3)), rng.standard_normal((n, 3)))
    got = kinetre.skin(body, body_graph, pose)
    g, idx, w = body_graph.nodes, body_graph.vertex_nodes, body_graph.vertex_weights.astype(np.float64)
    v = body.vertices
    per = (np.einsum("vkab,vkb->vka", pose.rotations[idx], v[:, None] - g[idx]) + g[idx]
           + pose.translations[idx])
    assert np.allclose(got, np.einsum("vk,vka->va", w, per), atol=1e-12)


def test_node_matrices_are_the_shader_form(body_graph):
    rng = np.random.default_rng(1)
    n = body_graph.node_count
    pose = kinetre.GraphPose(rng.standard_normal((n, 3, 3)), rng.standard_normal((n, 3)))
    m = pose.node_matrices(body_graph.nodes)
    p = rng.standard_normal(3)
    j = 5
    direct = pose.rotations[j] @ (p - body_graph.nodes[j]) + body_graph.nodes[j] + pose.translations[j]
    assert np.allclose(m[j] @ np.append(p, 1.0), np.append(direct, 1.0))


def test_skin_vertices_accepts_float32_weights():
    v = np.zeros((3, 3))
    idx = np.zeros((3, 4), np.int32)
    w = np.tile(np.float32([1, 0, 0, 0]), (3, 1))
    m = np.eye(4)[None].copy()
    m[0, :3, 3] = [1, 2, 3]
    assert np.allclose(skin_vertices(v, idx, w, m), [[1, 2, 3]] * 3)


def test_skin_vertices_writes_into_out(body, body_graph):
    rng = np.random.default_rng(2)
    n = body_graph.node_count
    pose = kinetre.GraphPose(np.eye(3) + 0.2 * rng.standard_normal((n, 3, 3)), rng.standard_normal((n, 3)))
    m = pose.node_matrices(body_graph.nodes)
    out = np.full_like(body.vertices, np.nan)
    got = skin_vertices(body.vertices, body_graph.vertex_nodes, body_graph.vertex_weights, m, out=out)
    assert got is out
    assert np.array_equal(out, kinetre.skin(body, body_graph, pose))


# ---- SkinTable: the float32 per-frame path ----------------------------------------------------------

def _random_pose(n, seed, scale=0.2):
    rng = np.random.default_rng(seed)
    return kinetre.GraphPose(np.eye(3) + scale * rng.standard_normal((n, 3, 3)), rng.standard_normal((n, 3)))


def _diagonal(points):
    return float(np.linalg.norm(np.ptp(points, axis=0)))


@pytest.fixture(scope="module")
def armadillo_rig(data_dir):
    mesh = kinetre.load_mesh(data_dir / "meshes" / "armadillo.obj")
    return mesh, kinetre.build_graph(mesh, nodes=256, seed=0)


@pytest.mark.slow
def test_table_agrees_with_float64_path_on_a_real_mesh(armadillo_rig):
    mesh, graph = armadillo_rig
    m = _random_pose(graph.node_count, 3).node_matrices(graph.nodes)
    table = SkinTable.prepare(mesh.vertices, graph.vertex_nodes, graph.vertex_weights, graph.node_count)
    got = table.skin(m)
    want = skin_vertices(mesh.vertices, graph.vertex_nodes, graph.vertex_weights, m)
    assert got.dtype == np.float32 and got.shape == want.shape
    assert len(mesh.vertices) > 2 * CHUNK  # several chunks: their last vertices take the 3-store path
    assert np.abs(got - want).max() < 1e-5 * _diagonal(want)


def test_table_keeps_the_vertex_order(armadillo_rig):
    # a shuffled mesh gives the same rows, shuffled the same way: every output row is its own vertex's
    mesh, graph = armadillo_rig
    m = _random_pose(graph.node_count, 4).node_matrices(graph.nodes)
    order = np.random.default_rng(5).permutation(len(mesh.vertices))
    v, idx, w = mesh.vertices[order], graph.vertex_nodes[order], graph.vertex_weights[order]
    got = SkinTable.prepare(v, idx, w, graph.node_count).skin(m)
    want = skin_vertices(mesh.vertices, graph.vertex_nodes, graph.vertex_weights, m)[order]
    assert np.abs(got - want).max() < 1e-5 * _diagonal(want)


def test_table_far_from_the_origin_and_at_chunk_edges(body, body_graph):
    # a mesh 1000 sizes away (rest positions are stored relative to the box centre) and vertex counts
    # around the chunk size: one vertex, a chunk's last vertex, a chunk and one more
    far = body.vertices + 1000.0 * _diagonal(body.vertices)
    m = _random_pose(body_graph.node_count, 6).node_matrices(body_graph.nodes)
    for count in (1, 2, CHUNK - 1, CHUNK, CHUNK + 1):
        rows = np.arange(count) % len(far)
        v, idx, w = far[rows], body_graph.vertex_nodes[rows], body_graph.vertex_weights[rows]
        got = SkinTable.prepare(v, idx, w, body_graph.node_count).skin(m)
        want = skin_vertices(v, idx, w, m)
        assert np.abs(got - want).max() < 1e-5 * max(_diagonal(want), 1e-3) + 1e-7 * np.abs(want).max()
    assert SkinTable.prepare(far[:0], body_graph.vertex_nodes[:0], body_graph.vertex_weights[:0],
                             body_graph.node_count).skin(m).shape == (0, 3)


def test_table_skins_directions_with_the_linear_part(body, body_graph):
    m = _random_pose(body_graph.node_count, 7).node_matrices(body_graph.nodes)
    m[:, :3, 3] = 0.0
    table = SkinTable.prepare(body.normals, body_graph.vertex_nodes, body_graph.vertex_weights,
                              body_graph.node_count, directions=True)
    assert np.array_equal(table.origin, np.zeros(3))
    want = skin_vertices(body.normals, body_graph.vertex_nodes, body_graph.vertex_weights, m)
    assert np.abs(table.skin(m) - want).max() < 1e-5 * np.abs(want).max()


def test_table_writes_into_out_and_checks_it(body, body_graph):
    m = _random_pose(body_graph.node_count, 8).node_matrices(body_graph.nodes)
    table = SkinTable.prepare(body.vertices, body_graph.vertex_nodes, body_graph.vertex_weights,
                              body_graph.node_count)
    assert table.nodes.dtype == np.uint16 and table.rest.dtype == np.float32
    out = np.full((len(body.vertices), 3), np.nan, np.float32)
    assert table.skin(m, out) is out
    assert np.array_equal(out, table.skin(m))
    with pytest.raises(ValueError, match="float32"):
        table.skin(m, np.empty((len(body.vertices), 3)))
    with pytest.raises(ValueError, match="node matrices"):
        table.skin(m[:-1])
    with pytest.raises(ValueError, match="node indices"):
        SkinTable.prepare(body.vertices, body_graph.vertex_nodes, body_graph.vertex_weights, 3)


@pytest.mark.slow
def test_table_with_more_nodes_than_uint16_holds():
    rng = np.random.default_rng(9)
    n = 70_000
    v = rng.standard_normal((5000, 3))
    idx = rng.integers(0, n, (5000, 4))
    w = rng.random((5000, 4)).astype(np.float32)
    w /= w.sum(axis=1, keepdims=True)
    m = _random_pose(n, 10).node_matrices(rng.standard_normal((n, 3)))
    table = SkinTable.prepare(v, idx, w, n)
    assert table.nodes.dtype == np.uint32
    want = skin_vertices(v, idx, w, m)
    assert np.abs(table.skin(m) - want).max() < 1e-5 * _diagonal(want)
