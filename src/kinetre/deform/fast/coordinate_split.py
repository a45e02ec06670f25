"""The per-coordinate part K of JᵀJ, fixed per rig, and its sparse factor.

In Sumner's parametrisation E_reg (Eq. 4), E_con (Eq. 5) and E_rig's translation gap (Eq. 7) are linear
in (R, t) and act identically and separately on x, y and z: coordinate a of every residual involves only
row a of each R_j and t_j[a], with the same coefficients for a = 0, 1, 2. So with per coordinate the 4N
unknowns (R_j[a, :], t_j[a]),

    JᵀJ = P · blockdiag(K, K, K) · Pᵀ + (E_rot node blocks) + (E_rig bridge blocks),

and K (4N × 4N) depends only on the graph, the constraint carriers and the set of tracked constraints,
never on the pose. We factor K_σ = K + σ I_R once per tracked set (σ on the R rows: the rotation
average of E_rot's 9×9 block is exactly 2 w_rot I, E_rig's R_j-R_j block is w_rig I per bridge), and use
it to precondition CG on the true Gauss-Newton system (`cg.py`, `preconditioner.py`).
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np
from scipy.sparse import csc_matrix, csr_matrix, diags, identity

from .coarse_space import prolongation, regions
from ..factor import NotPositiveDefinite
from ..normal_equations import NormalEquations, positions, scatter

try:  # optional: the `cholmod` extra
    from sksparse.cholmod import analyze
except ImportError:  # pragma: no cover - exercised only without scikit-sparse
    analyze = None


def _coordinate_columns(nodes: int) -> np.ndarray:
    """Columns of coordinate 0's unknowns in the solver layout, ordered 4 j + b: R_j[0, b], t_j[0]."""
    return (12 * np.arange(nodes)[:, None] + np.array([0, 1, 2, 9])).reshape(-1)


def _coordinate_rows(rows: int, stride: int, offset: int = 0) -> np.ndarray:
    """Rows of coordinate 0 in a residual block laid out `stride` rows per item, x at `offset`."""
    return stride * np.arange(rows // stride) + offset


class CoordinateSplit:
    """K per tracked set and the factor of K_σ, for one rig.

    Attributes
    ----------
    nodes : int
    sigma : (4N,) float64, the shift on K's diagonal (0 on the t rows)
    factorisations : int, numeric factorisations of K_σ so far
    region, offsets : (N,) region of each node and (N, 3) its offset from the region's centroid, for the
        coarse space (`coarse_space.py`; `coarse_regions` regions, 0: none)
    """

    CACHE = 4  # tracked sets kept factored: a flickering joint costs no refactorisation

    def __init__(self, system: NormalEquations, backend: str | None = None, coarse_regions: int = 0):
        nodes = system.n // 12
        self.nodes = nodes
        w = system.weights
        cols = _coordinate_columns(nodes)
        j_reg = system.j_reg[_coordinate_rows(system.j_reg.shape[0], 3)][:, cols]
        j_con = system.j_con[_coordinate_rows(system.j_con.shape[0], 3)][:, cols]
        bridges = system.bridges
        k_const = w.reg * (j_reg.T @ j_reg)
        if len(bridges):
            j_gap = system.j_gap[_coordinate_rows(system.j_gap.shape[0], 3)][:, cols]
            k_const = k_const + w.rig * (j_gap.T @ j_gap)
        self.j_con = j_con.tocsr()
        self.w_con = w.con
        # σ: 2 w_rot (E_rot averaged over rotations) + w_rig per bridge at the node (its exact R_j-R_j block)
        per_node = 2.0 * w.rot + w.rig * np.bincount(bridges.reshape(-1), minlength=nodes)
        self.sigma = np.zeros((nodes, 4))
        self.sigma[:, :3] = per_node[:, None]
        self.sigma = self.sigma.reshape(-1)
        self.shift = np.repeat(self.sigma, 3)  # σ in the coordinate layout of `hessian.py`

        def structural(m):
            m = m.copy()
            m.data = np.ones_like(m.data)
            return m

        pattern = (structural(k_const) + structural(j_con).T @ structural(j_con)
                   + identity(4 * nodes, format="csr")).tocsc()
        pattern.sort_indices()
        self.indptr, self.indices = pattern.indptr.astype(np.int64), pattern.indices.astype(np.int64)
        self._indptr32, self._indices32 = pattern.indptr.astype(np.int32), pattern.indices.astype(np.int32)
        self.const_data = scatter(self.indptr, self.indices, 4 * nodes, k_const)
        self.diag_pos = positions(self.indptr, self.indices, 4 * nodes, np.arange(4 * nodes), np.arange(4 * nodes))
        # K in 4 × 4 node blocks for `hessian.hessian_times` (88 % of their entries are in K's pattern): block
        # row pointers, block columns, and where each pattern entry goes in the blocks (B × 16, row-major)
        row = np.repeat(np.arange(4 * nodes), np.diff(self.indptr))  # symmetric: CSC columns are CSR rows
        key, block = np.unique((row // 4) * nodes + self.indices // 4, return_inverse=True)
        self._block_ptr = np.zeros(nodes + 1, np.int32)
        self._block_ptr[1:] = np.cumsum(np.bincount(key // nodes, minlength=nodes))
        self._block_col = (key % nodes).astype(np.int32)
        self._block_pos = 16 * block + 4 * (row % 4) + self.indices % 4
        self.shift_data = np.zeros(len(self.indices))
        self.shift_data[self.diag_pos] = self.sigma
        self.backend = backend or ("cholmod" if analyze is not None else "superlu")
        if self.backend == "cholmod" and analyze is None:
            raise ImportError("scikit-sparse is not installed (pip install 'kinetre[cholmod]')")
        # the unknowns in a fill-reducing order of the nodes: a node's 4 stay together, so the factor is made of
        # dense 4 × 4 blocks (`_factor`)
        self.node_order = self._node_order(pattern)
        self._perm = (4 * self.node_order[:, None] + np.arange(4)).reshape(-1)
        if self.backend == "cholmod":
            ones = self._matrix(np.ones(len(self.indices)))
            self._symbolic = analyze(ones[self._perm][:, self._perm], mode="simplicial", ordering_method="natural")
        self._cache: OrderedDict = OrderedDict()
        self.factorisations = 0
        self.region, self.offsets = regions(system.g, system.edges, coarse_regions) if coarse_regions else \
            (np.zeros(nodes, np.int64), np.zeros((nodes, 3)))
        self._prolongation = prolongation(self.region, self.offsets, int(self.region.max()) + 1) \
            if coarse_regions else None

    def _matrix(self, data: np.ndarray) -> csc_matrix:
        n = 4 * self.nodes
        return csc_matrix((data, self._indices32, self._indptr32), shape=(n, n))

    def k_data(self, active: np.ndarray) -> np.ndarray:
        """K's values on the pattern for the per-constraint scales `active` (L,)."""
        s2 = np.asarray(active, dtype=np.float64) ** 2
        m = self.j_con.T @ (self.j_con.multiply(s2[:, None]).tocsr())
        return self.const_data + self.w_con * scatter(self.indptr, self.indices, 4 * self.nodes, m)

    def for_active(self, active: np.ndarray):
        """(K in 4 × 4 node blocks (block row pointers (N + 1,), block columns, blocks (B, 16) row-major),
        factor tuple for `preconditioner.py`, K's (N, 4, 4) diagonal blocks) for this tracked set."""
        return self._for_active(active)[:3]

    def frame_data(self, active: np.ndarray):
        """Everything a PCG frame needs for this tracked set, from one cache lookup: `for_active`'s three,
        P_cᵀ K P_c (4m, 4m; (0, 0) without a coarse space: `coarse_space.py`), and K's diagonal in the
        coordinate layout (4N,)."""
        return self._for_active(active)

    def _for_active(self, active: np.ndarray):
        key = np.asarray(active, dtype=np.float64).tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            self._cache.move_to_end(key)
            return hit
        data = self.k_data(active)
        blocks = np.zeros((len(self._block_col), 16))
        blocks.reshape(-1)[self._block_pos] = data
        k = (self._block_ptr, self._block_col, blocks)
        shifted = self._matrix(data + self.shift_data)
        self.factorisations += 1
        p = self._prolongation
        kc = np.zeros((0, 0)) if p is None else np.ascontiguousarray((p.T @ (self._matrix(data) @ p)).toarray())
        hit = (k, self._factor(shifted), self._node_blocks(data), kc, data[self.diag_pos])
        self._cache[key] = hit
        if len(self._cache) > self.CACHE:
            self._cache.popitem(last=False)
        return hit

    def _node_blocks(self, data: np.ndarray) -> np.ndarray:
        """K's (N, 4, 4) diagonal blocks (node j's own 4 unknowns per coordinate)."""
        col = np.repeat(np.arange(4 * self.nodes), np.diff(self.indptr))
        own = (col // 4) == (self.indices // 4)
        out = np.zeros((self.nodes, 4, 4))
        out[col[own] // 4, self.indices[own] % 4, col[own] % 4] = data[own]
        return out

    def _node_order(self, pattern: csc_matrix) -> np.ndarray:
        """A fill-reducing elimination order (N,) of the nodes, from the backend's ordering of the node graph
        (two nodes adjacent when K couples any of their unknowns)."""
        coo = pattern.tocoo()
        n = self.nodes
        graph = csc_matrix((np.ones(len(coo.row)), (coo.row // 4, coo.col // 4)), shape=(n, n))
        graph = graph + n * identity(n, format="csc")  # diagonally dominant: any pivoting keeps the diagonal
        if self.backend == "cholmod":
            return analyze(graph, mode="simplicial", ordering_method="best").P().astype(np.int64)
        from scipy.sparse.linalg import splu
        lu = splu(graph.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        return np.argsort(lu.perm_c).astype(np.int64)

    def _factor(self, matrix: csc_matrix):
        """The Cholesky factor L of K_σ[perm][:, perm] = L Lᵀ, perm keeping each node's 4 unknowns together
        (`node_order`), in 4 × 4 blocks: (block row pointers (N + 1,), block columns, strictly lower blocks
        (B, 16) row-major, inverses of the diagonal blocks (N, 16), node_order (N,), shift σ (12N,) in the
        coordinate layout). A block times a node's 12 coordinate-layout entries is 48 multiply-adds on
        contiguous data where the scalar CSR factor read an index per 3 (`preconditioner.coordinate_solve`), which
        pays although the blocks hold 28 % more entries than the scalar factor's own ordering fills)."""
        a = csc_matrix(matrix[self._perm][:, self._perm])
        if self.backend == "cholmod":
            lower = self._symbolic.cholesky(a).L()
        else:
            from scipy.sparse.linalg import splu
            lu = splu(a, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
            if not (np.array_equal(lu.perm_r, np.arange(a.shape[0])) and np.array_equal(lu.perm_c, lu.perm_r)):
                raise NotPositiveDefinite("K_σ needed pivoting: not positive definite")
            # A = L U with L unit lower and U = D Lᵀ (no pivoting, symmetric A): L D^½ is the Cholesky factor
            lower = lu.L @ diags(np.sqrt(lu.U.diagonal()))
        blocks = csr_matrix(lower).tobsr(blocksize=(4, 4))
        blocks.sort_indices()
        row = np.repeat(np.arange(self.nodes), np.diff(blocks.indptr))
        own = blocks.indices == row
        inverse = lower_inverse(blocks.data[own])  # one diagonal block per row, in row order
        ptr = np.zeros(self.nodes + 1, np.int32)
        ptr[1:] = np.cumsum(np.bincount(row[~own], minlength=self.nodes))
        return (ptr, blocks.indices[~own].astype(np.int32), np.ascontiguousarray(blocks.data[~own].reshape(-1, 16)),
                np.ascontiguousarray(inverse.reshape(-1, 16)), self.node_order.astype(np.int32), self.shift)


def lower_inverse(lower: np.ndarray) -> np.ndarray:
    """Inverses (..., n, n) of lower-triangular matrices (..., n, n), by forward substitution over the whole
    stack at once. Stacked `np.linalg.inv` makes one LAPACK call per matrix, and a threaded BLAS synchronises its
    threads in each: on a busy machine hundreds of 4 × 4 inverses then take a large fraction of a second."""
    n = lower.shape[-1]
    out = np.zeros_like(lower, dtype=np.float64)
    diagonal = np.diagonal(lower, axis1=-2, axis2=-1)
    for i in range(n):
        out[..., i, i] = 1.0 / diagonal[..., i]
        for j in range(i):  # row i of L·X = I below the diagonal: Σ_k L[i,k] X[k,j] = 0
            out[..., i, j] = -np.einsum("...k,...k->...", lower[..., i, j:i], out[..., j:i, j]) / diagonal[..., i]
    return out
