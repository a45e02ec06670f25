"""Eq. 2 skinning weights: each vertex follows its k = 4 nearest nodes, linear falloff, normalised.

Nodes are ranked by the orientation-aware D (Eq. 6, with the vertex normal), so a vertex on a chair
leg is not pulled by the leg beside it. w_j = 1 − d_j / d_max with d_max the distance to the
(k+1)-th nearest node; rows sum to 1. Where fewer than k+1 nodes have a finite D (normals facing
away everywhere), that vertex falls back to Euclidean ranking.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from .distance import distance_5d

K = 4


@njit(cache=True)
def _insert(best_d, best_i, d, i):
    # keep best_d sorted ascending; drop the largest
    m = best_d.shape[0]
    if d >= best_d[m - 1]:
        return
    p = m - 1
    while p > 0 and best_d[p - 1] > d:
        best_d[p] = best_d[p - 1]
        best_i[p] = best_i[p - 1]
        p -= 1
    best_d[p] = d
    best_i[p] = i


@njit(cache=True, parallel=True)
def _weights(vertices, vnormals, nodes, nnormals, cell, dims, out_idx, out_w):
    n = nodes.shape[0]
    nx_, ny_, nz_ = dims[0], dims[1], dims[2]
    # dense grid of node lists (nodes are few: the grid is small)
    head = np.full(nx_ * ny_ * nz_, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    inv = 1.0 / cell
    for a in range(n):
        i = min(max(int(nodes[a, 0] * inv), 0), nx_ - 1)
        j = min(max(int(nodes[a, 1] * inv), 0), ny_ - 1)
        k = min(max(int(nodes[a, 2] * inv), 0), nz_ - 1)
        c = (i * ny_ + j) * nz_ + k
        nxt[a] = head[c]
        head[c] = a
    k1 = K + 1
    nv = vertices.shape[0]
    chunk = 4096
    # chunks, not vertices, are the parallel unit: each owns its small sort buffers
    for c0 in prange((nv + chunk - 1) // chunk):
        best_d = np.empty(k1)
        best_i = np.empty(k1, np.int64)
        for v in range(c0 * chunk, min(nv, (c0 + 1) * chunk)):
            _weights_one(v, vertices, vnormals, nodes, nnormals, cell, nx_, ny_, nz_, head, nxt, inv, best_d,
                         best_i, out_idx, out_w)


@njit(cache=True, inline="always")
def _weights_one(v, vertices, vnormals, nodes, nnormals, cell, nx_, ny_, nz_, head, nxt, inv, best_d, best_i,
                 out_idx, out_w):
    n = nodes.shape[0]
    px, py, pz = vertices[v, 0], vertices[v, 1], vertices[v, 2]
    vx, vy, vz = vnormals[v, 0], vnormals[v, 1], vnormals[v, 2]
    best_d[:] = np.inf
    best_i[:] = -1
    ci = min(max(int(px * inv), 0), nx_ - 1)
    cj = min(max(int(py * inv), 0), ny_ - 1)
    ck = min(max(int(pz * inv), 0), nz_ - 1)
    for ring in range(0, 4):
        for i in range(max(ci - ring, 0), min(ci + ring, nx_ - 1) + 1):
            for j in range(max(cj - ring, 0), min(cj + ring, ny_ - 1) + 1):
                for k in range(max(ck - ring, 0), min(ck + ring, nz_ - 1) + 1):
                    if max(abs(i - ci), abs(j - cj), abs(k - ck)) != ring:
                        continue  # inner cells were visited in earlier rings
                    a = head[(i * ny_ + j) * nz_ + k]
                    while a >= 0:
                        dx = px - nodes[a, 0]
                        dy = py - nodes[a, 1]
                        dz = pz - nodes[a, 2]
                        # D >= Euclidean: a node this far cannot enter the best k+1
                        if dx * dx + dy * dy + dz * dz < best_d[K] * best_d[K]:
                            d = distance_5d(px, py, pz, vx, vy, vz, nodes[a, 0], nodes[a, 1],
                                            nodes[a, 2], nnormals[a, 0], nnormals[a, 1], nnormals[a, 2])
                            _insert(best_d, best_i, d, a)
                        a = nxt[a]
        # every node within Euclidean ring * cell of the vertex has been seen
        if best_d[K] <= ring * cell:
            break
    if not best_d[K] <= 3 * cell:
        # sparse neighbourhood: rank every node by D, then fall back to Euclidean if D runs out
        best_d[:] = np.inf
        best_i[:] = -1
        for a in range(n):
            d = distance_5d(px, py, pz, vx, vy, vz, nodes[a, 0], nodes[a, 1], nodes[a, 2],
                            nnormals[a, 0], nnormals[a, 1], nnormals[a, 2])
            _insert(best_d, best_i, d, a)
        if not np.isfinite(best_d[min(K, n - 1)]):
            best_d[:] = np.inf
            best_i[:] = -1
            for a in range(n):
                dx = px - nodes[a, 0]
                dy = py - nodes[a, 1]
                dz = pz - nodes[a, 2]
                _insert(best_d, best_i, np.sqrt(dx * dx + dy * dy + dz * dz), a)
    dmax = best_d[K] if np.isfinite(best_d[K]) else best_d[min(K, n - 1)] * 1.5 + 1e-300
    total = 0.0
    for q in range(K):
        if best_i[q] < 0:
            out_idx[v, q] = best_i[0]
            out_w[v, q] = 0.0
            continue
        out_idx[v, q] = best_i[q]
        w = 1.0 - best_d[q] / dmax if dmax > 0 else 1.0
        if w < 0.0:
            w = 0.0
        out_w[v, q] = w
        total += w
    if total > 0:
        for q in range(K):
            out_w[v, q] /= total
    else:
        for q in range(K):
            out_w[v, q] = 1.0 / K if best_i[q] >= 0 else 0.0


def skinning_weights(vertices: np.ndarray, vertex_normals: np.ndarray, nodes: np.ndarray,
                     node_normals: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex node indices and weights (Eq. 2), ranked by the orientation-aware D.

    Parameters
    ----------
    vertices, vertex_normals : (V, 3) float64
    nodes, node_normals : (N, 3) float64, N >= 1
    radius : float
        The sampling radius R (the search grid's cell size).

    Returns
    -------
    indices : (V, 4) int32
        Node indices (glTF JOINTS_0); with fewer than 4 nodes, unused slots repeat the first with
        weight 0.
    weights : (V, 4) float32
        Non-negative, each row summing to 1 (glTF WEIGHTS_0).
    """
    v = len(vertices)
    idx = np.zeros((v, K), dtype=np.int32)
    w = np.zeros((v, K), dtype=np.float64)
    origin = np.minimum(nodes.min(axis=0), vertices.min(axis=0))
    extent = np.maximum(nodes.max(axis=0), vertices.max(axis=0)) - origin
    cell = 2.0 * float(radius)  # most vertices find their k+1 nodes within one ring of cells
    while np.prod(np.floor(extent / cell) + 1) > 4_000_000:  # keep the dense node grid small
        cell *= 2.0
    dims = (np.floor(extent / cell) + 1).astype(np.int64)
    _weights(np.ascontiguousarray(vertices - origin), np.ascontiguousarray(vertex_normals, dtype=np.float64),
             np.ascontiguousarray(nodes - origin), np.ascontiguousarray(node_normals, dtype=np.float64),
             cell, dims, idx, w)
    w32 = w.astype(np.float32)
    # float32 rounding: put the residual on the largest weight so rows sum to 1 in float32 too
    w32[np.arange(v), np.argmax(w32, axis=1)] += np.float32(1.0) - w32.sum(axis=1)
    return idx, w32
