"""`build_graph`: mesh → orientation-aware nodes → edges → bridges → skinning weights (KinÊtre paper,
"Extending Embedded Deformation", Eq. 2, 6)."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import BadGraphError
from ..mesh.mesh import Mesh
from .edges import bridge_edges, connect_components, knn_edges
from .graph import DeformationGraph
from .pieces import keep_to_pieces, node_pieces
from .sampling import sample_nodes
from .weights import skinning_weights


def build_graph(mesh: Mesh, nodes: int | None = 128, radius: float | None = None, seed: int = 0,
                k: int = 4, weights: bool = True) -> DeformationGraph:
    """Build the deformation graph of a mesh, once per mesh.

    Parameters
    ----------
    mesh : Mesh
    nodes : int
        Target node count N (within ±10 %); 128 in the paper, 256 for big meshes.
    radius : float, optional
        Sampling radius R instead of a count (a level of detail in the mesh's units).
    seed : int
        Sampling seed; the graph is a function of (mesh, nodes/radius, seed).
    k : int
        Neighbours per node (4 in the paper).
    weights : bool
        False leaves `vertex_nodes` / `vertex_weights` empty, (0, 4), for a caller that computes them
        with `with_weights` beside other work (the nodes and edges do not depend on them).

    Returns
    -------
    DeformationGraph, always one connected component.
    """
    if nodes is not None and radius is None and nodes < 2:
        raise BadGraphError(f"{mesh.source or 'mesh'}: nodes must be at least 2, got {nodes}")
    sample = sample_nodes(mesh.vertices, mesh.faces, mesh.normals, nodes=nodes, radius=radius, seed=seed)
    positions, normals, r = sample.positions, sample.normals, sample.radius
    if len(positions) < 2:
        raise BadGraphError(f"{mesh.source or 'mesh'}: only {len(positions)} node fits at radius {r:.4g}; "
                            f"use a smaller radius")
    edges = knn_edges(positions, normals, k)
    edges, added = connect_components(positions, edges)
    bridges = bridge_edges(len(positions), edges) | added
    pieces = node_pieces(mesh.pieces.of_vertex, mesh.faces, sample.faces)
    graph = DeformationGraph(nodes=positions, normals=normals, edges=edges, bridges=bridges, radius=r,
                             vertex_nodes=np.empty((0, 4), np.int32), vertex_weights=np.empty((0, 4), np.float32),
                             pieces=pieces)
    return with_weights(graph, mesh) if weights else graph


def with_weights(graph: DeformationGraph, mesh: Mesh) -> DeformationGraph:
    """`graph` with the skinning weights of `mesh`'s vertices (Eq. 2) filled in, each vertex's kept to the
    mesh piece it lies on (`pieces.keep_to_pieces`)."""
    idx, w = skinning_weights(mesh.vertices, mesh.normals, graph.nodes, graph.normals, graph.radius)
    if graph.pieces is not None and len(graph.pieces) == graph.node_count:
        idx, w = keep_to_pieces(idx, w, mesh.vertices, mesh.pieces, graph.nodes, graph.pieces)
    return dataclasses.replace(graph, vertex_nodes=idx, vertex_weights=w)
