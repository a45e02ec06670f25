"""Where the mesh stands in the room: uniform scale, yaw about +Y and a translation (world = s R local + p)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..mesh.mesh import Mesh
from ..mesh.normals import vertex_normals
from ..skeleton.models import Skeleton


@dataclass(frozen=True)
class Placement:
    """The mesh's model transform.

    Attributes
    ----------
    scale : float
        Uniform scale s > 0.
    position : (3,) tuple of float
        Translation p in metres.
    yaw : float
        Rotation about +Y in radians.
    """

    scale: float = 1.0
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw: float = 0.0

    @property
    def rotation(self) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])

    def matrix(self) -> np.ndarray:
        """(4, 4) float64 local → world."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.rotation
        m[:3, 3] = self.position
        return m

    @classmethod
    def fitted(cls, skeleton: Skeleton, mesh: Mesh, yaw: float = 0.0) -> "Placement":
        """The mesh scaled to the skeleton's height and stood where it stands (the studio's "fit"; paper:
        scale to height): its tracked joints' centre, on their lowest point."""
        tracked = skeleton.positions[skeleton.tracked]
        centre = tracked.mean(axis=0)
        return cls(skeleton.height / float(np.ptp(mesh.vertices[:, 1])),
                   (float(centre[0]), float(tracked[:, 1].min()), float(centre[2])), yaw)

    def to_local(self, skeleton: Skeleton) -> Skeleton:
        """The skeleton in the mesh's own frame: l = Rᵀ (x − p) / s."""
        rt = self.rotation.T
        inv = 1.0 / self.scale
        return skeleton.transformed(inv, rt, -inv * (rt @ np.asarray(self.position, dtype=np.float64)))

    def as_dict(self) -> dict:
        return {"scale": self.scale, "position": list(self.position), "yaw": self.yaw,
                "matrix": self.matrix().T.reshape(-1).tolist()}  # column-major, as three.js Matrix4.elements


def beside(boxes: list[tuple[np.ndarray, np.ndarray]], mesh: Mesh, like: Placement, gap: float = 0.3) -> Placement:
    """Where a mesh added to a scene stands: with the scale and yaw of `like` (the first mesh's placement),
    on its floor and at its depth, `gap` metres to the +x side of every world-space (min, max) box in
    `boxes` (the meshes already there), so that no two meshes overlap."""
    right = max((float(hi[0]) for _, hi in boxes), default=float(like.position[0]))
    left = float((like.scale * mesh.vertices @ like.rotation.T)[:, 0].min())
    return Placement(like.scale, (right + gap - left, float(like.position[1]), float(like.position[2])), like.yaw)


def standing_mesh(mesh: Mesh, height: float = 1.6) -> Mesh:
    """The mesh scaled to `height` metres tall, centred on x = z = 0 with its lowest point on y = 0.

    Meshes come in any unit (a teapot 3.15 units tall, a scan in millimetres); the studio works in
    metres so that the attachment distances (10 cm) mean the same on every mesh.
    """
    lo, hi = mesh.bounds
    extent = float(hi[1] - lo[1]) or float(np.max(hi - lo))
    s = height / extent
    centre = np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])
    vertices = (mesh.vertices - centre) * s
    return Mesh(vertices=vertices, faces=mesh.faces, normals=vertex_normals(vertices, mesh.faces), uvs=mesh.uvs,
                colors=mesh.colors, material=mesh.material, source=mesh.source)
