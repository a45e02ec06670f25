"""CPU skinning, Eq. 2: φ(v) = Σ_j w_j (R_j (v − g_j) + g_j + t_j) — the formula the GPU shader uses.

`skin_vertices` blends in float64 from any inputs (the reference); `SkinTable` prepares a mesh once and
blends every frame in float32 (video frames; 1M vertices in a few ms on one core).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..graph.graph import DeformationGraph
from ..jit import njit, prange, slp_vectorizer
from ..mesh.mesh import Mesh, bounding_box
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


CHUNK = 4096  # vertices per parallel task (on one thread the chunks run in order)


@njit(inline="always")
def _blend(rest, nodes, weights, columns, v):
    # Σ_q w_q C_q [x y z 1], C_q = the 4 columns of node j's matrix, 4 lanes each, in columns[j]. Written lane
    # by lane so that LLVM's SLP vectoriser makes each line one 4-wide multiply-add: a vertex is 16 of them,
    # with no gather (j varies per vertex). Unsigned node indices spare numba's negative-index checks.
    x, y, z = rest[v, 0], rest[v, 1], rest[v, 2]
    a0 = a1 = a2 = a3 = np.float32(0.0)
    for q in range(4):
        w = weights[v, q]
        j = nodes[v, q]
        a0 += w * (columns[j, 0] * x + columns[j, 4] * y + columns[j, 8] * z + columns[j, 12])
        a1 += w * (columns[j, 1] * x + columns[j, 5] * y + columns[j, 9] * z + columns[j, 13])
        a2 += w * (columns[j, 2] * x + columns[j, 6] * y + columns[j, 10] * z + columns[j, 14])
        a3 += w * (columns[j, 3] * x + columns[j, 7] * y + columns[j, 11] * z + columns[j, 15])
    return a0, a1, a2, a3


@njit(inline="always")
def _skin_run(rest, nodes, weights, columns, out):
    # one 4-lane store per vertex at 3v: its 4th lane lands on the next vertex's x, which is written right
    # after; the last vertex gets 3 stores. Indices counted from 0 here, so LLVM sees them non-negative and
    # drops numba's wraparound selects (which kept the stores from merging).
    flat = out.reshape(-1)
    n = rest.shape[0]
    for v in range(n - 1):
        a0, a1, a2, a3 = _blend(rest, nodes, weights, columns, v)
        flat[3 * v] = a0
        flat[3 * v + 1] = a1
        flat[3 * v + 2] = a2
        flat[3 * v + 3] = a3
    a0, a1, a2, _ = _blend(rest, nodes, weights, columns, n - 1)
    flat[3 * n - 3] = a0
    flat[3 * n - 2] = a1
    flat[3 * n - 1] = a2


@njit(cache=True, parallel=True, fastmath={"contract"})
def _skin32(rest, nodes, weights, columns, out):
    n = rest.shape[0]
    for chunk in prange((n + CHUNK - 1) // CHUNK):
        start, stop = chunk * CHUNK, min(n, (chunk + 1) * CHUNK)
        _skin_run(rest[start:stop], nodes[start:stop], weights[start:stop], columns, out[start:stop])
    return out


_VECTORISED: set = set()  # node index dtypes whose _skin32 this process compiled or loaded with SLP on


@dataclass(frozen=True, eq=False)
class SkinTable:
    """A mesh's skinning inputs prepared once for CPU skinning every frame: Eq. 2 in float32.

    A vertex reads 36 bytes and writes 12 (`skin_vertices`: 64 and 24); per frame the node matrices become
    a float32 table of 64 bytes a node (16 kB at 256 nodes: it stays in L1). Vertices keep the mesh's order,
    so outputs line up with faces, UVs and the exported buffers as they are: sorting them by dominant node
    gains nothing while the table sits in L1, and writing results back to the mesh's order costs more.

    Attributes
    ----------
    rest : (V, 3) float32
        Rest positions minus `origin` (float32 then keeps ~1e-7 of the mesh's size wherever it sits).
    origin : (3,) float64
        The bounding box's centre; zero for directions (normals).
    nodes : (V, 4) uint16, or uint32 above 65536 nodes
    weights : (V, 4) float32
    node_count : int
    """

    rest: np.ndarray
    origin: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray
    node_count: int

    @classmethod
    def prepare(cls, vertices: np.ndarray, nodes: np.ndarray, weights: np.ndarray, node_count: int,
                directions: bool = False) -> "SkinTable":
        """From (V, 3) points (or directions: no origin), (V, 4) node indices in [0, node_count) and weights."""
        vertices, nodes = np.asarray(vertices, dtype=np.float64), np.asarray(nodes)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or nodes.shape != (len(vertices), 4) \
                or np.shape(weights) != nodes.shape:
            raise ValueError(f"skinning needs (V, 3) vertices and (V, 4) nodes and weights, got "
                             f"{vertices.shape}, {nodes.shape} and {np.shape(weights)}")
        if nodes.size and (nodes.min() < 0 or nodes.max() >= node_count):
            raise ValueError(f"skinning node indices must lie in [0, {node_count})")
        origin = np.zeros(3)
        if len(vertices) and not directions:
            origin = bounding_box(vertices).mean(axis=0)
        index = np.uint16 if node_count <= 65536 else np.uint32
        return cls(np.ascontiguousarray(vertices - origin, dtype=np.float32), origin,
                   np.ascontiguousarray(nodes, dtype=index), np.ascontiguousarray(weights, dtype=np.float32),
                   int(node_count))

    def columns(self, node_matrices: np.ndarray) -> np.ndarray:
        """(N, 16) float32: the 4 columns of each M_j as it acts on rest = v − origin, 4 lanes each."""
        m = np.asarray(node_matrices, dtype=np.float64)
        if m.shape != (self.node_count, 4, 4):
            raise ValueError(f"skinning needs ({self.node_count}, 4, 4) node matrices, got {m.shape}")
        columns = np.empty((self.node_count, 4, 4), np.float32)
        columns[:, :3] = m[:, :, :3].transpose(0, 2, 1)
        columns[:, 3] = m[:, :, 3] + m[:, :, :3] @ self.origin  # M (r + o) = A r + (A o + b)
        return columns.reshape(-1, 16)

    def skin(self, node_matrices: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """(V, 3) float32 positions under the (N, 4, 4) node matrices (directions: matrices with zero
        translation). `out`, a C-contiguous (V, 3) float32 array, receives them when given (a frame loop
        then allocates nothing)."""
        n = len(self.rest)
        if out is None:
            out = np.empty((n, 3), np.float32)
        elif out.shape != (n, 3) or out.dtype != np.float32 or not out.flags.c_contiguous:
            raise ValueError(f"skinning writes into a C-contiguous ({n}, 3) float32 array, got "
                             f"{out.dtype} {out.shape}")
        args = (self.rest, self.nodes, self.weights, self.columns(node_matrices), out)
        if n == 0:
            return out
        if self.nodes.dtype in _VECTORISED:
            return _skin32(*args)
        with slp_vectorizer():  # the first call compiles or loads the kernel
            _skin32(*args)
        _VECTORISED.add(self.nodes.dtype)
        return out


def skin(mesh: Mesh, graph: DeformationGraph, pose: GraphPose) -> np.ndarray:
    """Deformed vertex positions of `mesh` under `pose` (Eq. 2).

    Returns
    -------
    (V, 3) float64
    """
    return skin_vertices(mesh.vertices, graph.vertex_nodes, graph.vertex_weights,
                         pose.node_matrices(graph.nodes))
