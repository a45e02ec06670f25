"""A straightforward Gauss-Newton reference for `make bench`: build the full J with scipy each
iteration, form JᵀJ by a sparse-sparse product, solve with `scipy.sparse.linalg.spsolve`.

This is how the paper describes its unoptimised solver; it is not used by the library.
"""
from __future__ import annotations

import time

import numpy as np
from scipy.sparse import diags, vstack
from scipy.sparse.linalg import spsolve

from kinetre.deform import energy as en
from kinetre.deform import jacobian as jac


def reference_iteration(graph, constraints, targets, active, x, weights, lam=1e-6):
    """One damped GN step the plain way; returns (new x, seconds spent)."""
    t0 = time.perf_counter()
    R = x[:, :9].reshape(-1, 3, 3)
    t = x[:, 9:]
    g, edges = graph.nodes, graph.edges
    bridges = graph.edges[graph.bridges]
    s = np.repeat(active, 3)
    blocks = [np.sqrt(weights.rot) * jac.rotation_jacobian(R),
              np.sqrt(weights.reg) * jac.regularization_jacobian(g, edges),
              np.sqrt(weights.con) * diags(s) @ jac.constraint_jacobian(g, constraints)]
    res = [np.sqrt(weights.rot) * en.rotation_residuals(R).reshape(-1),
           np.sqrt(weights.reg) * en.regularization_residuals(R, t, g, edges).reshape(-1),
           np.sqrt(weights.con) * s * en.constraint_residuals(R, t, g, constraints, targets).reshape(-1)]
    if len(bridges):
        blocks.append(np.sqrt(weights.rig) * jac.rigidity_jacobian(R, g, bridges))
        res.append(np.sqrt(weights.rig) * en.rigidity_residuals(R, t, g, bridges).reshape(-1))
    J = vstack(blocks).tocsr()
    r = np.concatenate(res)
    H = (J.T @ J).tocsc()
    H = H + diags(lam * H.diagonal())
    delta = spsolve(H, -(J.T @ r))
    return x + delta.reshape(x.shape), time.perf_counter() - t0
