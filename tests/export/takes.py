"""Synthetic takes and reference maths shared by the export tests (no Kinetre skinning code)."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from kinetre.deform.pose import GraphPose
from kinetre.graph.graph import DeformationGraph
from kinetre.mesh.mesh import Mesh
from kinetre.skeleton.models import KINECT20, Skeleton

DATA = (Path(__file__).resolve().parents[2] / ".." / "shared" / "data").resolve()
NODE_DIR = Path(__file__).resolve().parent / "node"


def reference_skin(mesh: Mesh, graph: DeformationGraph, pose: GraphPose) -> np.ndarray:
    """phi(v) = sum_j w_j (R_j (v - g_j) + g_j + t_j) (Eq. 2), in plain numpy."""
    idx, w = graph.vertex_nodes, graph.vertex_weights.astype(np.float64)
    v = mesh.vertices[:, None, :] - graph.nodes[idx]                             # (V, 4, 3)
    moved = np.einsum("vkij,vkj->vki", pose.rotations[idx], v) + graph.nodes[idx] + pose.translations[idx]
    return np.einsum("vk,vki->vi", w, moved)


def synthetic_graph(mesh: Mesh, nodes: int, rng: np.random.Generator) -> DeformationGraph:
    """Nodes on random vertices; 4 nearest nodes per vertex with Eq. 2's linear fall-off weights."""
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


def capsule(seed: int = 4):
    """(mesh, graph, poses, fps): a UV-mapped capsule along z with a 12-frame bend, 40 nodes."""
    rng = np.random.default_rng(seed)
    tm = trimesh.creation.capsule(height=1.0, radius=0.2, count=[24, 24])
    uv = np.c_[np.arctan2(tm.vertices[:, 1], tm.vertices[:, 0]) / (2 * np.pi) + 0.5,
               (tm.vertices[:, 2] - tm.vertices[:, 2].min()) / np.ptp(tm.vertices[:, 2])].astype(np.float32)
    mesh = Mesh(vertices=np.asarray(tm.vertices, float), faces=np.asarray(tm.faces, np.int32),
                normals=np.asarray(tm.vertex_normals, float), uvs=uv)
    graph = synthetic_graph(mesh, 40, rng)
    return mesh, graph, bend_poses(graph, 12, rng), 24.0


# A Kinect-20 T-pose in metres (+Y up, facing +Z), hip centre 1 m above the ground.
TPOSE = {
    "HipCenter": (0, 1.0, 0), "Spine": (0, 1.2, 0), "ShoulderCenter": (0, 1.45, 0), "Head": (0, 1.65, 0),
    "ShoulderLeft": (-0.18, 1.42, 0), "ElbowLeft": (-0.45, 1.42, 0), "WristLeft": (-0.7, 1.42, 0),
    "HandLeft": (-0.78, 1.42, 0), "ShoulderRight": (0.18, 1.42, 0), "ElbowRight": (0.45, 1.42, 0),
    "WristRight": (0.7, 1.42, 0), "HandRight": (0.78, 1.42, 0), "HipLeft": (-0.1, 0.95, 0),
    "KneeLeft": (-0.1, 0.52, 0), "AnkleLeft": (-0.1, 0.1, 0), "FootLeft": (-0.1, 0.03, 0.1),
    "HipRight": (0.1, 0.95, 0), "KneeRight": (0.1, 0.52, 0), "AnkleRight": (0.1, 0.1, 0),
    "FootRight": (0.1, 0.03, 0.1),
}


def rigid_take(frames=30, seed=0, model=KINECT20, rest=None):
    """Forward kinematics of the T-pose with random smooth local rotations and a moving root."""
    rng = np.random.default_rng(seed)
    rest = np.array([TPOSE[j] for j in model.joints], dtype=float) if rest is None else rest
    parents = np.array(model.parents)
    phase = rng.uniform(0, 2 * np.pi, size=(len(parents), 3))
    amp = rng.uniform(0.1, 0.8, size=(len(parents), 3))
    take = []
    for k in range(frames):
        local = Rotation.from_rotvec(amp * np.sin(0.2 * k + phase)).as_matrix()
        world_r = np.zeros((len(parents), 3, 3))
        pos = np.zeros((len(parents), 3))
        for i, p in enumerate(parents):
            if p < 0:
                world_r[i], pos[i] = local[i], rest[i] + [0.03 * k, 0.1 * np.sin(0.3 * k), 0]
            else:
                world_r[i] = world_r[p] @ local[i]
                pos[i] = pos[p] + world_r[p] @ (rest[i] - rest[p])
        take.append(Skeleton(model, pos, np.ones(len(parents), bool)))
    return take


def tracked_take(frames=30, seed=0):
    """What a tracker delivers: the rigid take plus 1 cm jitter (bone lengths vary) and lost joints."""
    rng = np.random.default_rng(seed)
    take = []
    for k, s in enumerate(rigid_take(frames, seed)):
        tracked = np.ones(20, bool)
        if k % 7 == 3:
            tracked[[7, 14, 15]] = False           # HandLeft, AnkleLeft, FootLeft lost
        if k == 10:
            tracked[0] = False                     # the root lost for a frame
        pos = s.positions + rng.normal(scale=0.01, size=(20, 3))
        pos[~tracked] = np.nan
        take.append(Skeleton(KINECT20, pos, tracked))
    return take


def placed(frames, mesh):
    """The frames scaled to the mesh's height, centred on it in x/z and standing on its lowest point."""
    lo, hi = mesh.bounds
    p = frames[0].positions[frames[0].tracked]
    scale = (hi[1] - lo[1]) / np.ptp(p[:, 1])
    foot = np.array([0.5 * (p[:, 0].min() + p[:, 0].max()), p[:, 1].min(), 0.5 * (p[:, 2].min() + p[:, 2].max())])
    target = np.array([0.5 * (lo[0] + hi[0]), lo[1], 0.5 * (lo[2] + hi[2])])
    return [f.transformed(scale=scale, translation=target - scale * foot) for f in frames]


def validate_gltf(path) -> dict:
    """Run the Khronos glTF validator (tests/export/node, installed by `make setup`) on `path`."""
    if not (NODE_DIR / "node_modules" / "gltf-validator").is_dir():
        raise RuntimeError(f"the glTF validator is not installed: run `npm ci` in {NODE_DIR} (make setup does)")
    out = subprocess.run(["node", str(NODE_DIR / "validate.mjs"), str(path)], capture_output=True, text=True,
                         timeout=300, check=True)
    return json.loads(out.stdout)
