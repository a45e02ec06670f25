"""CPU skinning, Eq. 2: φ(v) = Σ_j w_j (R_j (v − g_j) + g_j + t_j) — the formula the GPU shader uses."""
from __future__ import annotations

import numpy as np

from ..graph.graph import DeformationGraph
from ..jit import njit, prange
from ..mesh.mesh import Mesh
from .pose import GraphPose


@njit(cache=True, parallel=True, fastmath={"contract"})
def _skin(vertices, indices, weights, columns, out):
    # columns[j] = the 4 columns of node j's 4×4 matrix, 4 lanes each: one vertex is 4 lane-wise
    # multiply-adds per node (vectorised across the lanes), the 4th lane (homogeneous) unused
    for v in prange(vertices.shape[0]):
        x, y, z = vertices[v, 0], vertices[v, 1], vertices[v, 2]
        a0 = a1 = a2 = a3 = 0.0
        for q in range(4):
            j = indices[v, q]
            w = np.float64(weights[v, q])
            wx, wy, wz = w * x, w * y, w * z
            a0 += wx * columns[j, 0] + wy * columns[j, 4] + wz * columns[j, 8] + w * columns[j, 12]
            a1 += wx * columns[j, 1] + wy * columns[j, 5] + wz * columns[j, 9] + w * columns[j, 13]
            a2 += wx * columns[j, 2] + wy * columns[j, 6] + wz * columns[j, 10] + w * columns[j, 14]
            a3 += wx * columns[j, 3] + wy * columns[j, 7] + wz * columns[j, 11] + w * columns[j, 15]
        out[v, 0] = a0
        out[v, 1] = a1
        out[v, 2] = a2
    return out


def skin_vertices(vertices: np.ndarray, indices: np.ndarray, weights: np.ndarray,
                  node_matrices: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Linear blend of node affines: (V, 3) vertices, (V, 4) indices/weights, (N, 4, 4) matrices → (V, 3).

    `out`, a (V, 3) float64 C-contiguous array, receives the result when given (a frame loop then
    allocates nothing).
    """
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    if out is None:
        out = np.empty_like(vertices)
    columns = np.ascontiguousarray(np.asarray(node_matrices, dtype=np.float64).transpose(0, 2, 1)).reshape(-1, 16)
    # weights stay float32 (as stored for glTF): a float64 copy of a 1M-vertex table costs more than
    # the blend itself
    return _skin(vertices, np.ascontiguousarray(indices), np.ascontiguousarray(weights), columns, out)


def skin(mesh: Mesh, graph: DeformationGraph, pose: GraphPose) -> np.ndarray:
    """Deformed vertex positions of `mesh` under `pose` (Eq. 2).

    Returns
    -------
    (V, 3) float64
    """
    return skin_vertices(mesh.vertices, graph.vertex_nodes, graph.vertex_weights,
                         pose.node_matrices(graph.nodes))
