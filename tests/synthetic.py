"""Synthetic meshes and skeletons for tests: a T-pose and a capsule body every joint lies inside, a hand held
like a spider and a five-legged creature shaped like it."""
from __future__ import annotations

import dataclasses

import numpy as np
import trimesh

import kinetre
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.motion.fit import yaw_rotation
from kinetre.skeleton.models import FINGER_JOINTS, HAND21, KINECT20, Skeleton

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


# A hand held like a spider and a five-legged creature shaped like it (hand puppets).
SPLAY = np.radians([95.0, 40.0, 0.0, -35.0, -70.0])  # thumb .. little finger, about +Y from +Z
PHALANX = np.array([0.045, 0.03, 0.022])             # metres, knuckle to tip
REST = np.radians(30.0)                              # each joint bends the finger this far down


def spread_hand(curl, wrist=(0.0, 0.12, 0.0)) -> np.ndarray:
    """(21, 3) a hand held like a spider: palm level, fingers splayed round the wrist, each phalanx bent a
    further `curl[f]` (radians) down from the one before."""
    p = np.zeros((21, 3))
    p[0] = wrist
    for f, chain in enumerate(FINGER_JOINTS.values()):
        out = np.array([np.sin(SPLAY[f]), 0.0, np.cos(SPLAY[f])])
        x = p[0] + 0.035 * out
        p[HAND21.index(chain[0])] = x
        for k in range(3):
            a = (k + 1) * curl[f]
            x = x + PHALANX[k] * (np.cos(a) * out - np.sin(a) * np.array([0.0, 1.0, 0.0]))
            p[HAND21.index(chain[k + 1])] = x
    return p


def _segment_distance(p, a, b):
    ab = b - a
    t = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def star_hull(segments, radii, centre, subdivisions=5, steps=120) -> trimesh.Trimesh:
    """One connected surface round a union of capsules: a sphere's vertices pushed out along their rays from
    `centre` to the farthest point still inside a capsule."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    dirs = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    reach = max(max(np.linalg.norm(a - centre), np.linalg.norm(b - centre)) + r for (a, b), r in zip(segments, radii))
    s = np.linspace(0.0, reach, steps)
    points = (centre + dirs[:, None] * s[None, :, None]).reshape(-1, 3)
    inside = np.zeros(len(points), bool)
    for (a, b), r in zip(segments, radii):
        inside |= _segment_distance(points, a, b) < r
    inside = inside.reshape(len(dirs), steps)
    far = s[steps - 1 - np.argmax(inside[:, ::-1], axis=1)]
    return trimesh.Trimesh(centre + dirs * far[:, None], sphere.faces, process=False)


def hand_creature(scale: float = 3.0, yaw: float = 60.0, shift=(0.4, 0.0, -0.2)) -> tuple[trimesh.Trimesh, np.ndarray]:
    """A five-legged creature (one connected surface) shaped like the spread hand at rest: the palm its body,
    the fingers its legs; in its own units (`scale` x a hand's metres), turned `yaw` degrees about +Y and
    moved by `shift`, so a fit has to find its size, place and turn. Also returns its (5, 3) leg tips."""
    rest = spread_hand(np.full(5, REST))
    segments, radii = [], []
    for chain in FINGER_JOINTS.values():
        pts = rest[[0] + [HAND21.index(j) for j in chain]]
        segments.append((pts[0], pts[1]))
        radii.append(0.03)   # the palm: the body
        segments += list(zip(pts[1:-1], pts[2:]))
        radii += [0.011] * 3  # the legs
    turn, shift = yaw_rotation(yaw), np.asarray(shift, dtype=np.float64)
    hull = star_hull([(scale * a, scale * b) for a, b in segments], scale * np.array(radii),
                     scale * (rest[0] + [0.0, 0.0, 0.01]))
    tips = [HAND21.index(chain[-1]) for chain in FINGER_JOINTS.values()]
    return trimesh.Trimesh(hull.vertices @ turn.T + shift, hull.faces, process=False), scale * rest[tips] @ turn.T + shift
