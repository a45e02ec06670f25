"""The `GraphPose` dataclass: one affine transform per graph node (Eq. 1)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class GraphPose:
    """Node transforms A_j = (R_j, t_j), mapping v to R_j (v - g_j) + g_j + t_j (Eq. 1).

    Attributes
    ----------
    rotations : (N, 3, 3) float64
        The affine parts R_j (near-rotations; not orthonormalised).
    translations : (N, 3) float64
        The translations t_j.
    energy : float
        Total energy E (Eq. 8) at this pose, NaN when not the result of a solve.
    iterations : int
        Gauss-Newton iterations the solve took (0 for an identity or held pose).
    """

    rotations: np.ndarray
    translations: np.ndarray
    energy: float = float("nan")
    iterations: int = 0

    @staticmethod
    def identity(node_count: int) -> "GraphPose":
        return GraphPose(np.tile(np.eye(3), (node_count, 1, 1)), np.zeros((node_count, 3)), 0.0, 0)

    def node_matrices(self, nodes: np.ndarray) -> np.ndarray:
        """(N, 4, 4) float64 matrices M_j with M_j [v; 1] = A_j[v] (what a GPU skinning shader uses)."""
        n = self.rotations.shape[0]
        m = np.zeros((n, 4, 4))
        m[:, :3, :3] = self.rotations
        m[:, :3, 3] = nodes + self.translations - np.einsum("nij,nj->ni", self.rotations, nodes)
        m[:, 3, 3] = 1.0
        return m
