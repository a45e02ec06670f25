"""Synthetic meshes and skeletons for tests: a T-pose and a capsule body every joint lies inside."""
from __future__ import annotations

import dataclasses

import numpy as np
import trimesh

import kinetre
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.skeleton.models import KINECT20, Skeleton

def scaled_to_height(mesh: kinetre.Mesh, height: float = 1.7) -> kinetre.Mesh:
    """The mesh scaled to `height` metres tall, feet at y = 0, centred in x/z."""
    v = mesh.vertices
    s = height / np.ptp(v[:, 1])
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    out = (v - c) * s
    out[:, 1] -= out[:, 1].min()
    return dataclasses.replace(mesh, vertices=out)


def tpose(height: float = 1.7, centre=(0.0, 0.0, 0.0)) -> Skeleton:
    """A Kinect-20 T-pose of the given height, feet at y = centre[1], facing +Z."""
    h = height
    p = {
        "HipCenter": (0, 0.53, 0), "Spine": (0, 0.62, 0), "ShoulderCenter": (0, 0.82, 0), "Head": (0, 0.93, 0),
        "ShoulderLeft": (0.11, 0.80, 0), "ElbowLeft": (0.27, 0.80, 0), "WristLeft": (0.41, 0.80, 0),
        "HandLeft": (0.46, 0.80, 0), "ShoulderRight": (-0.11, 0.80, 0), "ElbowRight": (-0.27, 0.80, 0),
        "WristRight": (-0.41, 0.80, 0), "HandRight": (-0.46, 0.80, 0), "HipLeft": (0.06, 0.50, 0),
        "KneeLeft": (0.06, 0.28, 0), "AnkleLeft": (0.06, 0.04, 0), "FootLeft": (0.06, 0.0, 0.06),
        "HipRight": (-0.06, 0.50, 0), "KneeRight": (-0.06, 0.28, 0), "AnkleRight": (-0.06, 0.04, 0),
        "FootRight": (-0.06, 0.0, 0.06),
    }
    pos = np.array([p[j] for j in KINECT20.joints], dtype=np.float64) * h + np.asarray(centre, dtype=np.float64)
    return Skeleton(KINECT20, pos, np.ones(len(pos), dtype=bool))


def body_mesh(height: float = 1.7) -> kinetre.Mesh:
    """A crude humanoid made of capsules along the T-pose bones: a mesh every joint lies inside."""
    return capsule_body(tpose(height), radius=0.05 * height / 1.7)


def capsule_body(sk: Skeleton, radius: float = 0.05) -> kinetre.Mesh:
    """Capsules of `radius` around every bone of a skeleton frame."""
    height = 1.7 * radius / 0.05
    parts = []
    for a, b in sk.model.bones:
        pa, pb = sk.positions[a], sk.positions[b]
        length = np.linalg.norm(pb - pa)
        if length < 1e-6:
            continue
        cap = trimesh.creation.capsule(height=length, radius=0.05 * height / 1.7, count=[12, 12])
        # capsule axis is +Z, centred at the origin
        z = (pb - pa) / length
        x = np.cross(z, [0, 1, 0]) if abs(z[1]) < 0.9 else np.cross(z, [1, 0, 0])
        x /= np.linalg.norm(x)
        m = np.eye(4)
        m[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
        m[:3, 3] = 0.5 * (pa + pb)
        cap.apply_transform(m)
        parts.append(cap)
    return mesh_from_trimesh(trimesh.util.concatenate(parts), "body")
