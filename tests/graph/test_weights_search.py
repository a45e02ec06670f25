"""The pruned node search of `skinning_weights` gives exactly the k+1 nearest nodes under D: the same
indices and float32 weights, bit for bit, as ranking every node for every vertex (Eq. 2)."""
import numpy as np
import pytest
from numba import njit

import kinetre
from kinetre.graph.distance import distance_5d
from kinetre.graph.weights import K, _insert, skinning_weights


@njit(cache=True)
def _exhaustive(p, pn, q, qn, idx, w):
    # every vertex against every node by D, Euclidean where fewer than k+1 (or all) nodes have a finite D
    n = q.shape[0]
    for v in range(p.shape[0]):
        best_d = np.full(K + 1, np.inf)
        best_i = np.full(K + 1, -1)
        for a in range(n):
            _insert(best_d, best_i, distance_5d(p[v, 0], p[v, 1], p[v, 2], pn[v, 0], pn[v, 1], pn[v, 2],
                                                q[a, 0], q[a, 1], q[a, 2], qn[a, 0], qn[a, 1], qn[a, 2]), a)
        if not np.isfinite(best_d[min(K, n - 1)]):
            best_d[:] = np.inf
            best_i[:] = -1
            for a in range(n):
                _insert(best_d, best_i, np.sqrt(((p[v] - q[a]) ** 2).sum()), a)
        dmax = best_d[K] if np.isfinite(best_d[K]) else best_d[min(K, n - 1)] * 1.5 + 1e-300
        for j in range(K):
            idx[v, j] = best_i[j] if best_i[j] >= 0 else best_i[0]
            w[v, j] = max(1.0 - best_d[j] / dmax, 0.0) if best_i[j] >= 0 else 0.0
        if w[v].sum() > 0:
            w[v] /= w[v].sum()
        else:
            w[v] = (best_i[:K] >= 0) / K


def exhaustive_weights(vertices, normals, nodes, node_normals):
    origin = np.minimum(nodes.min(axis=0), vertices.min(axis=0))  # the same shift as the search
    idx = np.zeros((len(vertices), K), np.int32)
    w = np.zeros((len(vertices), K))
    _exhaustive(vertices - origin, normals, nodes - origin, node_normals, idx, w)
    w32 = w.astype(np.float32)
    w32[np.arange(len(w32)), np.argmax(w32, axis=1)] += np.float32(1.0) - w32.sum(axis=1)
    return idx, w32


@pytest.mark.slow
@pytest.mark.parametrize("name,nodes", [("armadillo.obj", 128), ("camelhead.off", 256), ("teapot.obj", 512),
                                        ("spot.obj", 64), ("sphereWithHole.stl", 300)])
def test_search_equals_ranking_every_node_on_real_meshes(data_dir, name, nodes):
    m = kinetre.load_mesh(data_dir / "meshes" / name)
    g = kinetre.build_graph(m, nodes=nodes, seed=1)
    idx, w = exhaustive_weights(m.vertices, m.normals, g.nodes, g.normals)
    got_idx, got_w = skinning_weights(m.vertices, m.normals, g.nodes, g.normals, g.radius)
    assert np.array_equal(got_idx, idx)
    assert np.array_equal(got_w, w)


@pytest.mark.parametrize("count,radius", [(1, 0.3), (3, 0.3), (5, 0.3), (40, 0.05), (40, 0.3), (400, 0.02)])
def test_search_equals_ranking_every_node_on_random_points(count, radius):
    # unstructured points and normals: many vertices see no nearby node (the all-node and Euclidean
    # fallbacks), few nodes (fewer than k + 1), radii far from the spacing the search is tuned for
    rng = np.random.default_rng(count)
    v = rng.random((3000, 3))
    vn = rng.standard_normal((3000, 3))
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    vn[:10] = 0.0  # degenerate normals: D is infinite to every node
    q = rng.random((count, 3)) * 1.2 - 0.1
    qn = rng.standard_normal((count, 3))
    qn /= np.linalg.norm(qn, axis=1, keepdims=True)
    idx, w = skinning_weights(v, vn, q, qn, radius)
    ref_idx, ref_w = exhaustive_weights(v, vn, q, qn)
    assert np.array_equal(idx, ref_idx)
    assert np.array_equal(w, ref_w)
    assert np.allclose(w.sum(axis=1), 1.0, atol=1e-6) and w.min() >= 0
