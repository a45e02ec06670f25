"""Sphere proxies of a mesh for the physics world (KinÊtre paper, "Physics-based Interactions").

Packing: visit the vertices in a random order (fixed seed); each vertex not yet inside a sphere becomes
the centre of a new sphere of radius r = 4 × mean edge length, and every vertex within r of it is marked
covered. When the loop ends, every vertex lies inside at least one sphere.

A sphere's centre *is* a mesh vertex, so it is carried by the deformation exactly like that vertex:
with the centre vertex's own 4 graph nodes and weights (Eq. 2), the proxy sits where the GPU-skinned
surface is, frame after frame. The page turns the centres into kinematic bodies (web/src/physics/).

    >>> packing = pack_spheres(mesh)                                      # doctest: +SKIP
    >>> centres = sphere_centres(packing, mesh, graph, pose)              # (S, 3), deformed
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..deform.pose import GraphPose
from ..deform.skinning import skin_vertices
from ..errors import BadMeshError
from ..graph.graph import DeformationGraph
from ..mesh.mesh import Mesh

RADIUS_FACTOR = 4.0  # r = 4 × mean edge length (paper)
# The studio's budget (ours): one Rapier step with 256 kinematic spheres and 100 boxes stays within a few
# ms in the page (benchmarks/bench_physics.py); a 380k-vertex scan would otherwise bring ~13 000 spheres.
STUDIO_MAX_SPHERES = 256


@dataclass(frozen=True, eq=False)
class SpherePacking:
    """Spheres covering a mesh's vertices.

    Attributes
    ----------
    centres : (S,) int64
        Vertex index of each sphere's centre, in the order they were placed.
    radius : float
        The common radius, in the mesh's units.
    factor : float
        radius / mean edge length (4 with the paper's rule; larger when `max_spheres` capped the count).
    """

    centres: np.ndarray
    radius: float
    factor: float

    @property
    def count(self) -> int:
        return int(len(self.centres))

    def skinning(self, graph: DeformationGraph) -> tuple[np.ndarray, np.ndarray]:
        """((S, 4) node indices, (S, 4) weights): each centre's own skinning data (Eq. 2)."""
        return graph.vertex_nodes[self.centres], graph.vertex_weights[self.centres]


def mean_edge_length(mesh: Mesh) -> float:
    """Mean length of the mesh's unique edges (an edge shared by two triangles counts once)."""
    f = mesh.faces
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]).astype(np.int64), axis=1)
    keys = np.unique(edges[:, 0] * len(mesh.vertices) + edges[:, 1])  # 1-D keys: np.unique's fast path (axis=0 sorts rows)
    a, b = np.divmod(keys, len(mesh.vertices))
    return float(np.linalg.norm(mesh.vertices[a] - mesh.vertices[b], axis=1).mean())


def _pack(tree: cKDTree, vertices: np.ndarray, order: np.ndarray, radius: float,
          limit: int | None = None) -> tuple[np.ndarray, float]:
    """(centres, covered fraction); stops early, with a fraction below 1, once `limit` is exceeded."""
    covered = np.zeros(len(vertices), bool)
    centres = []
    for v in order:
        if covered[v]:
            continue
        if limit is not None and len(centres) == limit:
            return np.asarray(centres, np.int64), float(covered.mean())
        centres.append(v)
        covered[tree.query_ball_point(vertices[v], radius)] = True
    return np.asarray(centres, np.int64), 1.0


def pack_spheres(mesh: Mesh, factor: float = RADIUS_FACTOR, seed: int = 0,
                 max_spheres: int | None = None) -> SpherePacking:
    """Greedy random sphere packing of `mesh`'s vertices (paper §Physics).

    factor : radius / mean edge length (the paper's 4).
    seed : the random visiting order; the same seed gives the same spheres.
    max_spheres : *(ours)* a budget for the physics step: while the paper's rule gives more spheres than
        this, the radius grows (by the square root of the excess, as the count goes like 1 / r² on a
        surface) and the packing is redone with the same visiting order. None keeps the paper's rule whatever the count.
    """
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise BadMeshError(f"{mesh.source or 'mesh'}: no triangles to pack spheres on")
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"sphere radius factor must be a positive number, got {factor}")
    if max_spheres is not None and max_spheres < 1:
        raise ValueError(f"max_spheres must be at least 1, got {max_spheres}")
    edge = mean_edge_length(mesh)
    if not (np.isfinite(edge) and edge > 0):
        raise BadMeshError(f"{mesh.source or 'mesh'}: mean edge length is {edge}; cannot size the spheres")
    vertices = np.ascontiguousarray(mesh.vertices, np.float64)
    tree = cKDTree(vertices)
    order = np.random.default_rng(seed).permutation(len(vertices))
    centres, covered = _pack(tree, vertices, order, factor * edge, max_spheres)
    while covered < 1.0:
        # over budget: the full count would be about limit / covered; an early stop keeps a 380k-vertex
        # scan's first try at the cost of a few hundred spheres, not thousands
        factor *= max(1.05, 1.02 * float(np.sqrt(len(centres) / max(covered, 1e-6) / max_spheres)))
        centres, covered = _pack(tree, vertices, order, factor * edge, max_spheres)
    return SpherePacking(centres, float(factor * edge), float(factor))


def sphere_centres(packing: SpherePacking, mesh: Mesh, graph: DeformationGraph, pose: GraphPose) -> np.ndarray:
    """(S, 3) sphere centres under `pose`: the centre vertices skinned with their own weights (Eq. 2)."""
    nodes, weights = packing.skinning(graph)
    return skin_vertices(mesh.vertices[packing.centres], nodes, weights, pose.node_matrices(graph.nodes))


@functools.lru_cache(maxsize=4)
def studio_packing(mesh: Mesh) -> SpherePacking:
    """The studio's packing of a mesh (seed 0, at most STUDIO_MAX_SPHERES), computed once per mesh."""
    return pack_spheres(mesh, max_spheres=STUDIO_MAX_SPHERES)
