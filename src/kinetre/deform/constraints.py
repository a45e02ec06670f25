"""Point constraints (Eq. 5): bind points p_ℓ embedded in the graph by 4 nodes each."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class PointConstraints:
    """Where each constraint sits in the graph at bind time.

    Attributes
    ----------
    points : (L, 3) float64
        Bind positions p_ℓ.
    nodes : (L, 4) int32
        The nodes that carry each constraint.
    weights : (L, 4) float64
        Their weights (linear falloff, rows summing to 1), so φ(p_ℓ) = Σ_i w_i A_i[p_ℓ] (Eq. 2).
    """

    points: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @staticmethod
    def empty() -> "PointConstraints":
        return PointConstraints(np.zeros((0, 3)), np.zeros((0, 4), np.int32), np.zeros((0, 4)))

    @staticmethod
    def concatenate(parts: list["PointConstraints"]) -> "PointConstraints":
        if not parts:
            return PointConstraints.empty()
        return PointConstraints(np.concatenate([p.points for p in parts]),
                                np.concatenate([p.nodes for p in parts]).astype(np.int32),
                                np.concatenate([p.weights for p in parts]))
