"""Fidelity measures shared by the fidelity benchmark and tests: an avatar's own clip posed by the independent
glTF player (gltf_player.py) as the reference, the unrigged mesh a user would bring, and the comparison of
a written animation with the reference vertex by vertex, in % of the character's height.

No Kinetre here: whatever produced the animation is judged by the glTF file it wrote.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from export.gltf_player import GltfFile

RATE = 30.0     # frames per second at which `kinetre animate` and `kinetre avatar` sample a glTF clip


def height_of(player: GltfFile) -> float:
    """The character's height: the rest pose's extent along +Y."""
    return float(np.ptp(player.vertices(0.0, None)[:, 1]))


def compared_frames(total: int, most: int) -> np.ndarray:
    """At most `most` of `total` frames, evenly spaced, the first and last included."""
    return np.unique(np.round(np.linspace(0, total - 1, min(total, most))).astype(int))


def errors(posed: np.ndarray, reference: np.ndarray, height: float) -> np.ndarray:
    """(F, V) distances between two (F, V, 3) sequences in % of `height`."""
    return 100.0 * np.linalg.norm(posed - reference, axis=2) / height


def figures(err: np.ndarray, still: np.ndarray) -> dict:
    """Mean, 95th percentile, maximum and worst frame's mean of (F, V) errors, beside the same for standing
    still (the first frame held)."""
    return {"mean_pct": round(float(err.mean()), 3), "p95_pct": round(float(np.percentile(err, 95)), 3),
            "max_pct": round(float(err.max()), 3), "worst_frame_pct": round(float(err.mean(axis=1).max()), 3),
            "still_mean_pct": round(float(still.mean()), 3),
            "still_worst_frame_pct": round(float(still.mean(axis=1).max()), 3),
            "beats_still": bool(err.mean() < still.mean())}


class Clip:
    """One animation of a rigged file, posed by the independent player at the frames a Kinetre command
    samples it at (start + i / RATE), at most `frames` of them compared."""

    def __init__(self, source, anim: str | int, frames: int, rate: float = RATE):
        """source: the file's path, or its GltfFile (one read for all of a file's clips)."""
        self.player = player = source if isinstance(source, GltfFile) else GltfFile(source)
        self.path = player.path
        self.anim = anim
        self.name = player.doc.animations[player.animation_index(anim)].name or str(anim)
        self.start, end = player.time_range(anim)
        self.rate = rate
        self.total = int(np.floor((end - self.start) * rate + 1e-6)) + 1
        self.index = compared_frames(self.total, frames)
        self.times = self.start + self.index / rate
        self.first = player.vertices(self.start, anim)
        self.reference = np.stack([player.vertices(t, anim) for t in self.times])
        self.height = height_of(player)
        self.still = errors(self.reference[:1], self.reference, self.height)

    def write_mesh(self, path) -> Path:
        """The body at the clip's first frame as an unrigged binary PLY (positions and triangles only)."""
        path = Path(path)
        faces = self.player.triangles()
        header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(self.first)}\nproperty float x\n"
                  f"property float y\nproperty float z\nelement face {len(faces)}\n"
                  "property list uchar int vertex_indices\nend_header\n").encode()
        tri = np.zeros(len(faces), dtype=[("n", "u1"), ("v", "<i4", 3)])
        tri["n"], tri["v"] = 3, faces
        path.write_bytes(header + self.first.astype("<f4").tobytes() + tri.tobytes())
        return path

    def played(self, out) -> np.ndarray:
        """(F, V', 3) a written animation posed at the compared frames (frame i at its i-th key time), and the
        file's player."""
        result = GltfFile(out)
        keys = np.unique(np.concatenate([t.times for t in result.channels(0)]))
        if len(keys) > 1 and abs((keys[1] - keys[0]) * self.rate - 1.0) > 1e-3:
            raise ValueError(f"{out}: keyed at {1 / (keys[1] - keys[0]):.3g} fps, the clip was sampled at {self.rate:g}")
        return np.stack([result.vertices(keys[min(i, len(keys) - 1)], 0) for i in self.index]), result

    def compare_mesh_animation(self, out) -> tuple[dict, float]:
        """Figures of an animation of the written mesh, and the largest rest-position gap (% of height).

        The mesh loader welds vertices by position, so each written vertex is matched to the output vertex
        at its rest position: the gap is zero up to float32 rounding when the correspondence is exact."""
        posed, result = self.played(out)
        gap, idx = cKDTree(result.vertices(0.0, None)).query(self.first)
        err = errors(posed[:, idx], self.reference, self.height)
        return figures(err, self.still), 100.0 * float(gap.max()) / self.height

    def compare_avatar_animation(self, out) -> dict:
        """Figures of a re-animation of the avatar itself (its meshes in their own order: vertex i is i)."""
        posed, _ = self.played(out)
        if posed.shape[1] != self.player.vertex_count:
            raise ValueError(f"{out}: {posed.shape[1]} vertices, the avatar has {self.player.vertex_count}")
        return figures(errors(posed, self.reference, self.height), self.still)

    def nearest_bone(self) -> dict:
        """Figures of the simplest rig: each vertex rigidly follows the artist bone nearest to it at the first
        frame. A bone runs from a joint to each child joint, or is a point at a childless joint, and moves
        with its joint; only joints that carry skin weight drive (IK targets and helpers do not)."""
        p = self.player
        joints = p.skin_joints()
        weight = p.joint_weights()
        index = {j: k for k, j in enumerate(joints)}
        parent = []
        for j in joints:
            a = p.parent.get(j)
            while a is not None and a not in index:
                a = p.parent.get(a)
            parent.append(-1 if a is None else index[a])
        deforms = [weight[j] > 0 for j in joints]
        first = np.stack(p.world_matrices(self.start, self.anim))[joints]
        head = first[:, :3, 3]
        ends = [(a, k, a) for k, a in enumerate(parent) if a >= 0 and deforms[a]]
        ends += [(k, k, k) for k in range(len(joints)) if k not in parent and deforms[k]]
        a = head[[e[0] for e in ends]]
        ab = head[[e[1] for e in ends]] - a
        driver = np.array([e[2] for e in ends])
        rel = self.first[:, None] - a[None]
        u = np.clip(np.einsum("vbc,bc->vb", rel, ab) / np.maximum((ab * ab).sum(1), 1e-300), 0.0, 1.0)
        bone = driver[np.linalg.norm(rel - u[..., None] * ab[None], axis=2).argmin(axis=1)]
        local = np.einsum("vij,vj->vi", np.linalg.inv(first)[bone], np.c_[self.first, np.ones(len(self.first))])
        posed = np.stack([np.einsum("vij,vj->vi", np.stack(p.world_matrices(t, self.anim))[joints][bone],
                                    local)[:, :3] for t in self.times])
        return figures(errors(posed, self.reference, self.height), self.still)
