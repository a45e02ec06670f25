"""CPU skinning equals Eq. 2 evaluated directly, and the identity pose changes nothing."""
import numpy as np

import kinetre
from kinetre.deform.skinning import skin_vertices


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
