"""The `DeformationGraph` dataclass: nodes, edges, bridges and per-vertex skinning data (KinÊtre paper, Eq. 1-2)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class DeformationGraph:
    """An embedded-deformation graph over a mesh.

    Attributes
    ----------
    nodes : (N, 3) float64
        Node positions g_j, samples on the surface.
    normals : (N, 3) float64
        Unit surface normals at the nodes (used to attach bone samples).
    edges : (E, 2) int32
        Undirected edges, each stored once with edges[:, 0] < edges[:, 1].
    bridges : (E,) bool
        Edges that carry the rigidity term E_rig (Eq. 7): MST-added edges, graph bridges and
        edges at cut vertices.
    radius : float
        The Poisson-disk radius R the nodes were sampled with.
    vertex_nodes : (V, 4) int32
        The 4 nodes that move each mesh vertex (glTF JOINTS_0).
    vertex_weights : (V, 4) float32
        Their weights, each row summing to 1 (glTF WEIGHTS_0).
    pieces : (N,) int32 or None
        Per node, the connected piece of the mesh it lies on (`pieces.node_pieces`); None when unknown.
    """

    nodes: np.ndarray
    normals: np.ndarray
    edges: np.ndarray
    bridges: np.ndarray
    radius: float
    vertex_nodes: np.ndarray
    vertex_weights: np.ndarray
    pieces: np.ndarray | None = None

    @property
    def node_count(self) -> int:
        return int(self.nodes.shape[0])

    def neighbours(self) -> list[np.ndarray]:
        """Per node, the (k,) int array of its neighbours."""
        n = self.node_count
        both = np.concatenate([self.edges, self.edges[:, ::-1]])
        order = np.argsort(both[:, 0], kind="stable")
        both = both[order]
        splits = np.searchsorted(both[:, 0], np.arange(n + 1))
        return [both[splits[i]:splits[i + 1], 1] for i in range(n)]
