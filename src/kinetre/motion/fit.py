"""Place a take in a mesh without a person in the loop: scale, face, centre and ground the bind frame.

Attachment distances (10 cm reach, 4 cm bones) and the energy weights are in metres, for human-sized
bodies, so the solve happens in the skeleton's metres: the mesh is scaled by `mesh_scale` to the height of
the bind skeleton, and the skeleton is turned about +Y to face the mesh's front, centred on the mesh's
bounding box in x/z and grounded (its lowest tracked joint at the mesh's lowest point). Results go back
to the mesh's own units (`output_scale`) unless the mesh is to be resized to the skeleton (`fit_mesh`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..deform.pose import GraphPose
from ..errors import BadMotionError
from ..graph.graph import DeformationGraph
from ..mesh.mesh import Mesh
from ..skeleton.models import KINECT20, Skeleton
from .take import Take


@dataclass(frozen=True)
class Placement:
    """Where a take goes relative to a mesh.

    Attributes
    ----------
    mesh_scale : float
        k: the mesh (and its graph) in the solve frame is k * vertices (metres of the skeleton).
    rotation : (3, 3) float64
        Turn applied to the skeleton: about +Y (a hand is also turned to hang by its fingers first).
    translation : (3,) float64
        Then added to the skeleton: x -> rotation @ x + translation, in the solve frame.
    output_scale : float
        Solve frame -> output file units: 1 / k (the mesh keeps its size, the motion is scaled to it)
        or 1 (`fit_mesh`: the mesh is resized to the skeleton).
    skeleton_scale : float
        The skeleton is scaled by this before the turn: 1 for people (the solve frame is their metres),
        the source-to-mesh size ratio for other skeletons (`align.fit_shapes`).
    method : str
        How it was found: "height" (a person fitted by height), "shapes" (`align.fit_shapes`) or "in place"
        (the source already stood inside the mesh, `in_place.in_place`).
    """

    mesh_scale: float
    rotation: np.ndarray
    translation: np.ndarray
    output_scale: float
    skeleton_scale: float = 1.0
    method: str = "height"

    def skeleton(self, frame: Skeleton) -> Skeleton:
        """A frame in the solve frame."""
        return frame.transformed(self.skeleton_scale, self.rotation, self.translation)

    def take(self, take: Take) -> Take:
        """Every frame of a take in the solve frame."""
        return take.transformed(self.skeleton_scale, self.rotation, self.translation)

    def mesh(self, mesh: Mesh) -> Mesh:
        """The mesh in the solve frame (uniform scaling keeps its normals)."""
        return mesh.scaled(self.mesh_scale)

    def graph(self, graph: DeformationGraph) -> DeformationGraph:
        """A graph built on the original mesh, in the solve frame (same edges, weights and normals)."""
        return dataclasses.replace(graph, nodes=graph.nodes * self.mesh_scale,
                                   radius=graph.radius * self.mesh_scale)

    def output_pose(self, pose: GraphPose) -> GraphPose:
        """A pose solved in the solve frame, for the output mesh: v' = sum w (R (v - g) + g + t) scales
        with the mesh, so only the translations change."""
        return GraphPose(pose.rotations, pose.translations * self.output_scale, pose.energy, pose.iterations)


def facing(frame: Skeleton) -> np.ndarray | None:
    """(3,) unit horizontal direction a Kinect-20 skeleton faces, or None (other models, or no
    shoulders and hips tracked). Left = +X for a body facing +Z with +Y up, so front = left x up."""
    if frame.model != KINECT20:
        return None
    left = np.zeros(3)
    for a, b in (("ShoulderLeft", "ShoulderRight"), ("HipLeft", "HipRight")):
        ia, ib = KINECT20.index(a), KINECT20.index(b)
        if frame.tracked[ia] and frame.tracked[ib]:
            left += frame.positions[ia] - frame.positions[ib]
    front = np.cross(left, [0.0, 1.0, 0.0])
    front[1] = 0.0
    n = np.linalg.norm(front)
    return front / n if n > 1e-9 else None


def yaw_rotation(degrees: float) -> np.ndarray:
    """(3, 3) rotation by `degrees` about +Y (+Z turns towards +X)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def fit_take(take: Take, mesh: Mesh, bind_frame: int = 0, fit_mesh: bool = False,
             yaw: float | None = None) -> Placement:
    """Place `take` in `mesh` from its bind frame.

    Parameters
    ----------
    take : Take (metres, +Y up)
    mesh : Mesh (any units, +Y up)
    bind_frame : int
        The frame whose pose is the bind (rest) pose.
    fit_mesh : bool
        Resize the mesh to the skeleton in the output instead of the motion to the mesh.
    yaw : float, optional
        Direction the skeleton faces, degrees about +Y from the mesh's front +Z. By default a Kinect-20
        skeleton is turned to face +Z; other skeletons keep their file's orientation, turned by `yaw`.

    Raises
    ------
    BadMotionError
        The bind frame tracks fewer than two joints or has no height.
    """
    frame = take.frame(bind_frame)
    pts = frame.positions[frame.tracked]
    where = take.source or "take"
    if len(pts) < 2:
        raise BadMotionError(f"{where}: bind frame {bind_frame} tracks {len(pts)} joint(s), need at least 2")
    skel_height = float(np.ptp(pts[:, 1]))
    if not skel_height > 1e-6:
        raise BadMotionError(f"{where}: bind frame {bind_frame} is flat (no height) and cannot be fitted")
    lo, hi = mesh.bounds
    extent = hi - lo
    # a flat mesh (a rug lying down) is sized by its diagonal rather than its zero height
    mesh_height = extent[1] if extent[1] > 0.05 * np.linalg.norm(extent) else float(np.linalg.norm(extent))
    k = skel_height / mesh_height

    front = facing(frame)
    turn = 0.0 if front is None else math.degrees(math.atan2(front[0], front[2]))
    rotation = yaw_rotation((yaw or 0.0) - turn)
    placed = pts @ rotation.T
    centre = 0.5 * (lo + hi) * k
    low = lo[1] * k
    bbox_mid = 0.5 * (placed.min(axis=0) + placed.max(axis=0))
    translation = np.array([centre[0] - bbox_mid[0], low - placed[:, 1].min(), centre[2] - bbox_mid[2]])
    return Placement(k, rotation, translation, 1.0 if fit_mesh else 1.0 / k)
