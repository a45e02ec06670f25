"""Fixtures for the export tests: a synthetic rigged take, the shared data folder, the glTF validator."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from kinetre.deform.pose import GraphPose
from kinetre.graph.graph import DeformationGraph
from kinetre.mesh.mesh import Mesh

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data"
NODE_DIR = Path(__file__).resolve().parent / "node"


@pytest.fixture
def data_dir() -> Path:
    return DATA.resolve()


def reference_skin(mesh: Mesh, graph: DeformationGraph, pose: GraphPose) -> np.ndarray:
    """phi(v) = sum_j w_j (R_j (v - g_j) + g_j + t_j) (Eq. 2), in plain numpy."""
    idx, w = graph.vertex_nodes, graph.vertex_weights.astype(np.float64)
    v = mesh.vertices[:, None, :] - graph.nodes[idx]                             # (V, 4, 3)
    moved = np.einsum("vkij,vkj->vki", pose.rotations[idx], v) + graph.nodes[idx] + pose.translations[idx]
    return np.einsum("vk,vki->vi", w, moved)


def synthetic_graph(mesh: Mesh, nodes: int, rng: np.random.Generator) -> DeformationGraph:
    """Nodes on random vertices; 4 nearest nodes per vertex with SPEC §1.4's linear fall-off weights."""
    g = mesh.vertices[rng.choice(len(mesh.vertices), nodes, replace=False)]
    d = np.linalg.norm(mesh.vertices[:, None, :] - g[None], axis=2)
    order = np.argsort(d, axis=1)[:, :5]
    dk = np.take_along_axis(d, order, axis=1)
    w = np.clip(1.0 - dk[:, :4] / dk[:, 4:5], 1e-6, None)
    w /= w.sum(axis=1, keepdims=True)
    normals = mesh.normals[np.argmin(d, axis=0)]
    return DeformationGraph(nodes=g, normals=normals, edges=np.zeros((0, 2), np.int32),
                            bridges=np.zeros(0, bool), radius=0.1, vertex_nodes=order[:, :4].astype(np.int32),
                            vertex_weights=w.astype(np.float32))


def bend_poses(graph: DeformationGraph, frames: int, rng: np.random.Generator, affine: float = 0.01):
    """A take that bends the mesh about the x axis progressively along z, plus a small non-rigid part
    (R_j = rotation x (I + affine * random symmetric)), as a real solve leaves near-rotations."""
    g = graph.nodes
    z = (g[:, 2] - g[:, 2].min()) / np.ptp(g[:, 2])
    poses = []
    for k in range(frames):
        angle = np.deg2rad(60.0) * np.sin(np.pi * k / max(frames - 1, 1)) * z           # (N,)
        rot = Rotation.from_rotvec(np.outer(angle, [1.0, 0.0, 0.0])).as_matrix()
        s = rng.normal(size=(len(g), 3, 3))
        rot = rot @ (np.eye(3) + affine * 0.5 * (s + s.transpose(0, 2, 1)))
        # move each node where the rigid bend about the lowest node takes it
        pivot = g[np.argmin(g[:, 2])]
        target = np.einsum("nij,nj->ni", Rotation.from_rotvec(np.outer(angle, [1, 0, 0])).as_matrix(), g - pivot)
        t = target + pivot - g + np.array([0.02 * k, 0.0, 0.0])
        poses.append(GraphPose(rot, t))
    return poses


@pytest.fixture
def capsule_take():
    """(mesh, graph, poses, fps): a UV-mapped capsule along z with a 12-frame bend, 40 nodes."""
    rng = np.random.default_rng(4)
    tm = trimesh.creation.capsule(height=1.0, radius=0.2, count=[24, 24])
    uv = np.c_[np.arctan2(tm.vertices[:, 1], tm.vertices[:, 0]) / (2 * np.pi) + 0.5,
               (tm.vertices[:, 2] - tm.vertices[:, 2].min()) / np.ptp(tm.vertices[:, 2])].astype(np.float32)
    mesh = Mesh(vertices=np.asarray(tm.vertices, float), faces=np.asarray(tm.faces, np.int32),
                normals=np.asarray(tm.vertex_normals, float), uvs=uv)
    graph = synthetic_graph(mesh, 40, rng)
    return mesh, graph, bend_poses(graph, 12, rng), 24.0


def validate_gltf(path) -> dict:
    """Run the Khronos glTF validator (tests/export/node, installed by `make setup`) on `path`."""
    if not (NODE_DIR / "node_modules" / "gltf-validator").is_dir():
        raise RuntimeError(f"the glTF validator is not installed: run `npm ci` in {NODE_DIR} (make setup does)")
    out = subprocess.run(["node", str(NODE_DIR / "validate.mjs"), str(path)], capture_output=True, text=True,
                         timeout=300, check=True)
    return json.loads(out.stdout)
