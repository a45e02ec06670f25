"""CPU skinning, Eq. 2: φ(v) = Σ_j w_j(v) (R_j (v − g_j) + g_j + t_j) — the formula the GPU shader uses."""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..graph.graph import DeformationGraph
from ..mesh.mesh import Mesh
from .pose import GraphPose


@njit(cache=True, parallel=True)
def _skin(vertices, indices, weights, m):
    out = np.empty_like(vertices)
    for v in prange(vertices.shape[0]):
        x, y, z = vertices[v, 0], vertices[v, 1], vertices[v, 2]
        ox = oy = oz = 0.0
        for q in range(4):
            j = indices[v, q]
            w = np.float64(weights[v, q])
            ox += w * (m[j, 0, 0] * x + m[j, 0, 1] * y + m[j, 0, 2] * z + m[j, 0, 3])
            oy += w * (m[j, 1, 0] * x + m[j, 1, 1] * y + m[j, 1, 2] * z + m[j, 1, 3])
            oz += w * (m[j, 2, 0] * x + m[j, 2, 1] * y + m[j, 2, 2] * z + m[j, 2, 3])
        out[v, 0] = ox
        out[v, 1] = oy
        out[v, 2] = oz
    return out


def skin_vertices(vertices: np.ndarray, indices: np.ndarray, weights: np.ndarray,
                  node_matrices: np.ndarray) -> np.ndarray:
    """Linear blend of node affines: (V, 3) vertices, (V, 4) indices/weights, (N, 4, 4) matrices → (V, 3)."""
    # weights stay float32 (as stored for glTF): a float64 copy of a 1M-vertex table costs more than
    # the blend itself
    return _skin(np.ascontiguousarray(vertices, dtype=np.float64), np.ascontiguousarray(indices),
                 np.ascontiguousarray(weights), np.ascontiguousarray(node_matrices, dtype=np.float64))


def skin(mesh: Mesh, graph: DeformationGraph, pose: GraphPose) -> np.ndarray:
    """Deformed vertex positions of `mesh` under `pose` (Eq. 2).

    Returns
    -------
    (V, 3) float64
    """
    return skin_vertices(mesh.vertices, graph.vertex_nodes, graph.vertex_weights,
                         pose.node_matrices(graph.nodes))
