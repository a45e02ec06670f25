"""Meshes for the studio: load one, stand it in metres, build its graph, and the payload the page skins."""
from __future__ import annotations

import base64
from importlib import resources
from pathlib import Path

import numpy as np

from ..graph.build import build_graph
from ..mesh.load import load_mesh
from ..mesh.mesh import Mesh
from ..mesh.upright import Upright, axis_name, find_upright, turned
from ..physics.spheres import studio_packing
from .placement import standing_mesh

NODES = 128  # graph size for meshes loaded in the studio (the paper's default)


def data_path(name: str) -> Path:
    """A file shipped in kinetre/data (the sample mesh and motion)."""
    return Path(str(resources.files("kinetre") / "data" / name))


def prepare_mesh(path: str, nodes: int = NODES, progress=lambda stage, fraction: None):
    """Load, stand upright in metres and build the graph: (Mesh, DeformationGraph). Raises KinetreError."""
    progress("reading", 0.05)
    mesh, graph, _ = prepare_upright(load_mesh(path), path, nodes, progress)
    return mesh, graph


def prepare_upright(raw: Mesh, path: str, nodes: int = NODES, progress=lambda stage, fraction: None,
                    up: str | None = None):
    """(Mesh, DeformationGraph, Upright) for a loaded mesh: turned +Y up (`up`, or as its file and shape
    say: mesh.upright), stood in metres, its graph built."""
    upright = find_upright(raw, path) if up is None else Upright(up, {}, f"{axis_name(up)} up, as chosen")
    mesh = standing_mesh(turned(raw, upright.up))
    progress("building graph", 0.3)
    graph = build_graph(mesh, nodes=nodes, seed=0)
    progress("packing physics spheres", 0.9)
    studio_packing(mesh)  # cached: the payload is then ready without blocking the server's event loop
    progress("ready", 1.0)
    return mesh, graph, upright


def mesh_payload(mesh: Mesh, graph, mesh_id: int, name: str) -> dict:
    """What the page needs to build a SkinnedMesh and its physics spheres: little-endian arrays as base64."""
    def b64(a, dtype):
        return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode()
    return {"id": mesh_id, "name": name, "vertexCount": int(len(mesh.vertices)),
            "nodeCount": graph.node_count,
            "positions": b64(mesh.vertices, "<f4"), "normals": b64(mesh.normals, "<f4"),
            "faces": b64(mesh.faces, "<u4"), "skinIndex": b64(graph.vertex_nodes, "<u2"),
            "skinWeight": b64(graph.vertex_weights, "<f4"), "nodes": b64(graph.nodes, "<f4"),
            "nodeNormals": b64(graph.normals, "<f4"),
            "spheres": b64(studio_packing(mesh).centres, "<u4"), "sphereRadius": studio_packing(mesh).radius}
