"""Eq. 2 skinning weights: each vertex follows its k = 4 nearest nodes, linear falloff, normalised.

Nodes are ranked by the orientation-aware D (Eq. 6, with the vertex normal), so a vertex on a chair
leg is not pulled by the leg beside it. w_j = 1 − d_j / d_max with d_max the distance to the
(k+1)-th nearest node; rows sum to 1. Where fewer than k+1 nodes have a finite D (normals facing
away everywhere), that vertex falls back to Euclidean ranking.

The search is exact and runs per block of nearby vertices rather than per vertex: vertices are bucketed
into cubes of side R/4; each cube gathers once the nodes within Euclidean ρ = 4R of its vertices' box,
dropping those that every normal of the cube's normal cone faces away from, and sorts them by a lower
bound on D over the cube (box distance / largest cosine over the cone). A vertex walks that list until the
bound reaches its current (k+1)-th D, or an upper bound on it (D to the previous vertex's k+1 nodes), and
evaluates D only where its squared form can beat that. A vertex whose (k+1)-th D exceeds ρ (normals turned
away from every nearby node) ranks all nodes instead. So the result is the true k + 1 nearest under D, the
same nodes and weights as a plain search over every node.
"""
from __future__ import annotations

import numpy as np

from ..jit import njit
from .distance import distance_5d

K = 4
REACH = 4.0  # ρ / R: the candidate radius of a cube; most vertices find their k+1 nodes within 2R
CUBE = 0.25  # cube side / R
_SAFE = 1.0 - 1e-12  # a lower bound may round above the D it bounds: prune only clearly beyond
_LENIENT = 1.0 + 1e-9  # the same for the squared test before D


@njit(cache=True, inline="always")
def _place(dist, idx, p, d, i):
    """Put (d, i) at slot p or before it, moving the larger entries before p one slot up (the step of an
    insertion sort; slots below p are sorted ascending)."""
    while p > 0 and dist[p - 1] > d:
        dist[p] = dist[p - 1]
        idx[p] = idx[p - 1]
        p -= 1
    dist[p] = d
    idx[p] = i


@njit(cache=True)
def _insert(best_d, best_i, d, i):
    # keep best_d sorted ascending; drop the largest
    m = best_d.shape[0]
    if d >= best_d[m - 1]:
        return
    _place(best_d, best_i, m - 1, d, i)


@njit(cache=True)
def _reset(best_d, best_i):
    for q in range(best_d.shape[0]):
        best_d[q] = np.inf
        best_i[q] = -1


@njit(cache=True, nogil=True)
def _bounds(vertices):
    """(3,), (3,): the corners of the vertices' bounding box, in one pass."""
    lo = vertices[0].copy()
    hi = vertices[0].copy()
    for v in range(1, vertices.shape[0]):
        for d in range(3):
            lo[d] = min(lo[d], vertices[v, d])
            hi[d] = max(hi[d], vertices[v, d])
    return lo, hi


@njit(cache=True, nogil=True)
def _bucket(vertices, origin, inv, dims):
    """Counting sort of the vertices by cube: (order, start) with cube c's vertices order[start[c]:start[c+1]]."""
    nv = vertices.shape[0]
    ny, nz = dims[1], dims[2]
    cube = np.empty(nv, np.int64)
    start = np.zeros(dims[0] * ny * nz + 1, np.int64)
    for v in range(nv):
        i = min(max(int((vertices[v, 0] - origin[0]) * inv), 0), dims[0] - 1)
        j = min(max(int((vertices[v, 1] - origin[1]) * inv), 0), ny - 1)
        k = min(max(int((vertices[v, 2] - origin[2]) * inv), 0), nz - 1)
        c = (i * ny + j) * nz + k
        cube[v] = c
        start[c + 1] += 1
    for c in range(start.shape[0] - 1):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(nv, np.int64)
    for v in range(nv):
        order[fill[cube[v]]] = v
        fill[cube[v]] += 1
    return order, start


@njit(cache=True)
def _node_grid(nodes, inv, dims):
    """Nodes bucketed in a dense grid: linked lists head[cell] → nxt[node]."""
    head = np.full(dims[0] * dims[1] * dims[2], -1, np.int64)
    nxt = np.full(nodes.shape[0], -1, np.int64)
    for a in range(nodes.shape[0]):
        i = min(max(int(nodes[a, 0] * inv), 0), dims[0] - 1)
        j = min(max(int(nodes[a, 1] * inv), 0), dims[1] - 1)
        k = min(max(int(nodes[a, 2] * inv), 0), dims[2] - 1)
        c = (i * dims[1] + j) * dims[2] + k
        nxt[a] = head[c]
        head[c] = a
    return head, nxt


@njit(cache=True, nogil=True)
def _weights(vertices, vnormals, nodes, nnormals, origin, order, start, reach, ginv, gdims, out_idx, out_w):
    # vertices are raw; nodes are already shifted by origin (so are the vertices inside, as p - origin)
    head, nxt = _node_grid(nodes, ginv, gdims)
    for c in range(start.shape[0] - 1):
        lo_v, hi_v = start[c], start[c + 1]
        if lo_v == hi_v:
            continue
        # the tight box of this cube's vertices (after the same shift as in the distances) and the cone of
        # their normals (axis, cosine of the half-angle, largest length)
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        axis = np.zeros(3)
        for s in range(lo_v, hi_v):
            v = order[s]
            for d in range(3):
                x = vertices[v, d] - origin[d]
                lo[d] = min(lo[d], x)
                hi[d] = max(hi[d], x)
                axis[d] += vnormals[v, d]
        length = np.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
        spread = 1.0  # cos of the half-angle
        longest = 0.0
        if length > 0:
            for d in range(3):
                axis[d] /= length
            for s in range(lo_v, hi_v):
                v = order[s]
                nv = np.sqrt(vnormals[v, 0] ** 2 + vnormals[v, 1] ** 2 + vnormals[v, 2] ** 2)
                longest = max(longest, nv)
                if nv > 0:
                    spread = min(spread, (axis[0] * vnormals[v, 0] + axis[1] * vnormals[v, 1]
                                          + axis[2] * vnormals[v, 2]) / nv)
        else:
            spread = -1.0  # no cone: the cosine bound stays the normals' lengths
            for s in range(lo_v, hi_v):
                v = order[s]
                longest = max(longest, np.sqrt(vnormals[v, 0] ** 2 + vnormals[v, 1] ** 2 + vnormals[v, 2] ** 2))
        cand, bound = _candidates(nodes, nnormals, lo, hi, axis, spread, longest, reach, head, nxt, ginv, gdims)
        best_d = np.empty(K + 1)
        best_i = np.empty(K + 1, np.int64)
        seed = np.full(K + 1, -1, np.int64)
        wq = np.empty(K)
        for s in range(lo_v, hi_v):
            _weights_one(order[s], vertices, vnormals, nodes, nnormals, origin, cand, bound, reach, seed, best_d,
                         best_i, wq, out_idx, out_w)


@njit(cache=True)
def _candidates(nodes, nnormals, lo, hi, axis, spread, longest, reach, head, nxt, ginv, gdims):
    """Nodes within Euclidean `reach` of the box [lo, hi] that some normal of the cone can see, by increasing
    lower bound on D over the box.

    With the vertex normals within angle α of `axis` (cos α = `spread`) and node a's normal at angle θ to
    it, every n_v · n_a ≤ |n_v| |n_a| cos(max(θ − α, 0)) =: c_a; D = √(|d|² + 8m) / cos ≥ |d| / c_a ≥ lb / c_a,
    and D = ∞ for every vertex when θ − α ≥ 90°.
    """
    alpha = np.arccos(max(min(spread, 1.0), -1.0)) + 1e-6  # rounding of the cone: widen it a little
    i0 = max(int((lo[0] - reach) * ginv), 0)
    i1 = min(int((hi[0] + reach) * ginv), gdims[0] - 1)
    j0 = max(int((lo[1] - reach) * ginv), 0)
    j1 = min(int((hi[1] + reach) * ginv), gdims[1] - 1)
    k0 = max(int((lo[2] - reach) * ginv), 0)
    k1 = min(int((hi[2] + reach) * ginv), gdims[2] - 1)
    idx = np.empty(nodes.shape[0], np.int64)
    dist = np.empty(nodes.shape[0])
    m = 0
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                a = head[(i * gdims[1] + j) * gdims[2] + k]
                while a >= 0:
                    g = 0.0
                    for d in range(3):
                        x = nodes[a, d]
                        gap = lo[d] - x if x < lo[d] else (x - hi[d] if x > hi[d] else 0.0)
                        g += gap * gap
                    g = np.sqrt(g)
                    if g <= reach:
                        na = np.sqrt(nnormals[a, 0] ** 2 + nnormals[a, 1] ** 2 + nnormals[a, 2] ** 2)
                        cos = 1.0
                        if na > 0:
                            c = (axis[0] * nnormals[a, 0] + axis[1] * nnormals[a, 1] + axis[2] * nnormals[a, 2]) / na
                            theta = np.arccos(max(min(c, 1.0), -1.0)) - alpha
                            cos = np.cos(theta) if theta > 0 else 1.0
                            if theta >= 0.5 * np.pi:
                                cos = 0.0
                        cos *= na * longest
                        if cos > 0:
                            idx[m] = a
                            dist[m] = g / cos
                            m += 1
                    a = nxt[a]
    # insertion sort (a cube's list is short), then the safety factor on the bounds
    for q in range(1, m):
        _place(dist, idx, q, dist[q], idx[q])
    for q in range(m):
        dist[q] *= _SAFE
    return idx[:m], dist[:m]


@njit(cache=True, inline="always")
def _weights_one(v, vertices, vnormals, nodes, nnormals, origin, cand, bound, reach, seed, best_d, best_i, wq,
                 out_idx, out_w):
    n = nodes.shape[0]
    px, py, pz = vertices[v, 0] - origin[0], vertices[v, 1] - origin[1], vertices[v, 2] - origin[2]
    vx, vy, vz = vnormals[v, 0], vnormals[v, 1], vnormals[v, 2]
    # an upper bound on the (k+1)-th D: the previous vertex's k + 1 nodes, ranked from this vertex
    upper = np.inf
    if seed[K] >= 0:
        upper = 0.0
        for q in range(K + 1):
            a = seed[q]
            upper = max(upper, distance_5d(px, py, pz, vx, vy, vz, nodes[a, 0], nodes[a, 1], nodes[a, 2],
                                           nnormals[a, 0], nnormals[a, 1], nnormals[a, 2]))
    _reset(best_d, best_i)
    for q in range(cand.shape[0]):
        th = min(best_d[K], upper)
        if bound[q] >= th:
            break  # D ≥ Euclidean ≥ bound for this node and every later one
        a = cand[q]
        qx, qy, qz = nodes[a, 0], nodes[a, 1], nodes[a, 2]
        nx, ny, nz = nnormals[a, 0], nnormals[a, 1], nnormals[a, 2]
        cos = vx * nx + vy * ny + vz * nz
        if cos <= 0.0:
            continue  # D = inf
        dx = px - qx
        dy = py - qy
        dz = pz - qz
        dd = dx * dx + dy * dy + dz * dz
        # the squared D times cos², without its root and division; lenient, so it only saves work
        e = dx * nx + dy * ny + dz * nz
        f = dx * vx + dy * vy + dz * vz
        if dd + 8.0 * min(e * e, f * f) <= th * th * cos * cos * _LENIENT:
            _insert(best_d, best_i, distance_5d(px, py, pz, vx, vy, vz, qx, qy, qz, nx, ny, nz), a)
    for q in range(K + 1):
        seed[q] = best_i[q]
    if not best_d[K] <= reach:
        # nodes beyond reach were not offered: rank every node by D, then fall back to Euclidean if D runs out
        _reset(best_d, best_i)
        for a in range(n):
            d = distance_5d(px, py, pz, vx, vy, vz, nodes[a, 0], nodes[a, 1], nodes[a, 2],
                            nnormals[a, 0], nnormals[a, 1], nnormals[a, 2])
            _insert(best_d, best_i, d, a)
        if not np.isfinite(best_d[min(K, n - 1)]):
            _reset(best_d, best_i)
            for a in range(n):
                dx = px - nodes[a, 0]
                dy = py - nodes[a, 1]
                dz = pz - nodes[a, 2]
                _insert(best_d, best_i, np.sqrt(dx * dx + dy * dy + dz * dz), a)
    dmax = best_d[K] if np.isfinite(best_d[K]) else best_d[min(K, n - 1)] * 1.5 + 1e-300
    total = 0.0
    for q in range(K):
        out_idx[v, q] = best_i[q] if best_i[q] >= 0 else best_i[0]
        w = 0.0
        if best_i[q] >= 0:
            w = max(1.0 - best_d[q] / dmax if dmax > 0 else 1.0, 0.0)
        wq[q] = w
        total += w
    for q in range(K):
        if total > 0:
            wq[q] /= total
        else:
            wq[q] = 1.0 / K if best_i[q] >= 0 else 0.0
    # float32 (glTF) rows summing to 1 in float32 too: the rounding residual goes to the largest weight
    big = 0
    for q in range(K):
        out_w[v, q] = np.float32(wq[q])
        if out_w[v, q] > out_w[v, big]:
            big = q
    s = out_w[v, 0]
    for q in range(1, K):
        s = s + out_w[v, q]
    out_w[v, big] = out_w[v, big] + (np.float32(1.0) - s)


def _grid(extent: np.ndarray, cell: float, limit: int) -> tuple[float, np.ndarray]:
    """A cell size ≥ `cell` (doubled as needed) whose dense grid over `extent` has at most `limit` cells."""
    while np.prod(np.floor(extent / cell) + 1) > limit:
        cell *= 2.0
    return cell, (np.floor(extent / cell) + 1).astype(np.int64)


def skinning_weights(vertices: np.ndarray, vertex_normals: np.ndarray, nodes: np.ndarray,
                     node_normals: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex node indices and weights (Eq. 2), ranked by the orientation-aware D.

    The kernels release the GIL: `kinetre animate` runs this in a thread beside the attach and solve.

    Parameters
    ----------
    vertices, vertex_normals : (V, 3) float64
    nodes, node_normals : (N, 3) float64, N >= 1
    radius : float
        The sampling radius R (nodes are about R apart: it sizes the search).

    Returns
    -------
    indices : (V, 4) int32
        Node indices (glTF JOINTS_0); with fewer than 4 nodes, unused slots repeat the first with
        weight 0.
    weights : (V, 4) float32
        Non-negative, each row summing to 1 (glTF WEIGHTS_0).
    """
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    v = len(vertices)
    idx = np.empty((v, K), dtype=np.int32)
    w = np.empty((v, K), dtype=np.float32)
    vlo, vhi = _bounds(vertices)
    origin = np.minimum(nodes.min(axis=0), vlo)
    extent = np.maximum(nodes.max(axis=0), vhi) - origin
    r = float(radius)
    # vertex cubes of R/4: a few hundred vertices each on a dense mesh, at most ~2 cubes per vertex
    cube, cdims = _grid(extent, CUBE * r, max(2 * v, 64))
    # node grid: cells of R hold about one node; kept small
    gcell, gdims = _grid(extent, r, 4_000_000)
    order, start = _bucket(vertices, origin, 1.0 / cube, cdims)
    _weights(vertices, np.ascontiguousarray(vertex_normals, dtype=np.float64),
             np.ascontiguousarray(nodes - origin), np.ascontiguousarray(node_normals, dtype=np.float64),
             origin, order, start, REACH * r, 1.0 / gcell, gdims, idx, w)
    return idx, w
