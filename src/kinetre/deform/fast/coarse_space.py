"""A coarse space of region-affine motions for the PCG preconditioner (ours): a few dozen extra unknowns
that carry the graph-wide slow modes, whole limbs or a whole unconstrained body turning.

Both parts of the preconditioner in `preconditioner.py` are poor on these modes: K_σ's shift σ I prices every
change of R_j at 2 w_rot although a rotation costs E_rot nothing, and the node blocks see one node at a time.
When few nodes are constrained (one arm possessing a body) CG then crawls, 10-40 iterations on some steps.

The nodes are split into regions (farthest-point seeds on the nodes, each node to the seed nearest along
the graph's edges). Region r's 12 coarse unknowns are an affine displacement field v ↦ F_r v + b_r of its
nodes: every node j of r gets ΔR_j = F_r, Δt_j = F_r (g_j − c_r) + b_r (c_r the region's centroid). E_reg
(Eq. 4) is zero on such a field inside a region, and an infinitesimal rigid rotation of a region in any
pose is one (F = [ω]× R for a region turned by R), as is a translation. With P the prolongation
(12N × 12m), the correction is z = P (Pᵀ H P)⁻¹ Pᵀ r. Pᵀ (K ⊗ I₃) P = (P_cᵀ K P_c) ⊗ I₃ is fixed per
rig and tracked set (`coordinate_split.py`); the node blocks, bridge blocks and damping are added per
Gauss-Newton step (`coarse_factor`), a dense Cholesky of 12m unknowns.

Coarse layout, as `hessian.py`'s: c[12 r + 3 b + a] is F_r[a, b] (b < 3) or b_r[a] (b = 3).
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from ...jit import njit


def regions(nodes: np.ndarray, edges: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Split graph nodes (N, 3) into `count` regions: farthest-point seeds, then each node to the seed
    nearest along the edges (E, 2) (Euclidean where no path leads). Returns (region (N,) int64, node
    offsets g_j − c_region (N, 3))."""
    n = len(nodes)
    count = max(1, min(count, n))
    seeds = [int(np.argmax(np.linalg.norm(nodes - nodes.mean(axis=0), axis=1)))]
    d = np.linalg.norm(nodes - nodes[seeds[0]], axis=1)
    for _ in range(count - 1):
        seeds.append(int(np.argmax(d)))
        d = np.minimum(d, np.linalg.norm(nodes - nodes[seeds[-1]], axis=1))
    seeds = np.array(seeds)
    length = np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
    graph = csr_matrix((np.r_[length, length], (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                       shape=(n, n))
    dist, _, source = dijkstra(graph, indices=seeds, min_only=True, return_predecessors=True)
    which = np.full(n, -1)
    which[seeds] = np.arange(len(seeds))
    region = np.where(np.isfinite(dist), which[np.maximum(source, 0)], -1)
    lost = region < 0
    if lost.any():
        region[lost] = np.argmin(np.linalg.norm(nodes[lost, None] - nodes[seeds][None], axis=2), axis=1)
    centroid = np.zeros((len(seeds), 3))
    np.add.at(centroid, region, nodes)
    centroid /= np.maximum(np.bincount(region, minlength=len(seeds)), 1)[:, None]
    return region.astype(np.int64), nodes - centroid[region]


def prolongation(region: np.ndarray, offsets: np.ndarray, count: int) -> csr_matrix:
    """P_c (4N × 4m): one coordinate's part of P, node unknowns (R_j[a, :], t_j[a]) from the region's
    (F_r[a, :], b_r[a])."""
    n = len(region)
    rows = np.concatenate([4 * np.arange(n)[:, None] + np.arange(3), np.repeat(4 * np.arange(n)[:, None] + 3, 4, 1)],
                          axis=1)
    cols = np.concatenate([4 * region[:, None] + np.arange(3), 4 * region[:, None] + np.arange(4)], axis=1)
    vals = np.concatenate([np.ones((n, 3)), offsets, np.ones((n, 1))], axis=1)
    return csr_matrix((vals.reshape(-1), (rows.reshape(-1), cols.reshape(-1))), shape=(4 * n, 4 * count))


@njit(cache=True)
def coarse_factor(kc, region, offsets, rot, rig, bridges, damp, out):
    """out (12m, 12m) ← the Cholesky factor (lower, reciprocal diagonal) of Pᵀ H P, from kc = P_cᵀ K P_c
    (4m, 4m) and the node blocks `rot`, bridge blocks `rig` and damping `damp` of `hessian.py`."""
    m4 = kc.shape[0]
    out[:] = 0.0
    for u in range(m4):
        for v in range(m4):
            for a in range(3):
                out[3 * u + a, 3 * v + a] = kc[u, v]
    for j in range(rot.shape[0]):
        o = 12 * region[j]
        for u in range(9):
            for v in range(9):
                out[o + u, o + v] += rot[j, u, v]
            out[o + u, o + u] += damp[12 * j + u]
        for a in range(3):  # Δt_j[a] = Σ_b d_b F[a, b] + b[a]: its damping on (F[a, :], b[a])
            dt = damp[12 * j + 9 + a]
            for b in range(4):
                pb = offsets[j, b] if b < 3 else 1.0
                for bb in range(4):
                    pbb = offsets[j, bb] if bb < 3 else 1.0
                    out[o + 3 * b + a, o + 3 * bb + a] += dt * pb * pbb
    for e in range(bridges.shape[0]):
        for s in range(2):
            os_ = 12 * region[bridges[e, s]]
            for ss in range(2):
                oss = 12 * region[bridges[e, ss]]
                for u in range(9):
                    for v in range(9):
                        out[os_ + u, oss + v] += rig[e, 9 * s + u, 9 * ss + v]
    n = out.shape[0]
    for c in range(n):
        d = out[c, c] - _dot(out, c, c, c)
        d = np.sqrt(d) if d > 0.0 else 1e150  # a region nothing holds: no correction there
        out[c, c] = 1.0 / d
        for r in range(c + 1, n):
            out[r, c] = (out[r, c] - _dot(out, r, c, c)) * out[c, c]


@njit(cache=True)
def _dot(a, r, c, count):
    """a[r, :count] · a[c, :count] with four accumulators (one would wait on each add: 2.5× slower)."""
    s0 = s1 = s2 = s3 = 0.0
    k = 0
    while k + 4 <= count:
        s0 += a[r, k] * a[c, k]
        s1 += a[r, k + 1] * a[c, k + 1]
        s2 += a[r, k + 2] * a[c, k + 2]
        s3 += a[r, k + 3] * a[c, k + 3]
        k += 4
    while k < count:
        s0 += a[r, k] * a[c, k]
        k += 1
    return (s0 + s1) + (s2 + s3)


@njit(cache=True)
def coarse_add(gfac, region, offsets, r, z):
    """z += P (Pᵀ H P)⁻¹ Pᵀ r, with the factor of `coarse_factor`."""
    n = gfac.shape[0]
    c = np.zeros(n)
    for j in range(region.shape[0]):  # Pᵀ r
        o, q = 12 * region[j], 12 * j
        for a in range(3):
            rt = r[q + 9 + a]
            for b in range(3):
                c[o + 3 * b + a] += r[q + 3 * b + a] + offsets[j, b] * rt
            c[o + 9 + a] += rt
    for i in range(n):
        s = c[i]
        for k in range(i):
            s -= gfac[i, k] * c[k]
        c[i] = s * gfac[i, i]
    for i in range(n - 1, -1, -1):
        s = c[i]
        for k in range(i + 1, n):
            s -= gfac[k, i] * c[k]
        c[i] = s * gfac[i, i]
    for j in range(region.shape[0]):  # P c
        o, q = 12 * region[j], 12 * j
        for a in range(3):
            t = c[o + 9 + a]
            for b in range(3):
                z[q + 3 * b + a] += c[o + 3 * b + a]
                t += offsets[j, b] * c[o + 3 * b + a]
            z[q + 9 + a] += t
