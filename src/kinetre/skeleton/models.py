"""Skeleton hierarchies (Kinect-20 of the KinÊtre paper, OpenNI-17 of the avateering paper's Fig. 3, MediaPipe's
21-landmark hand) and the `Skeleton` frame: joint positions plus a tracked mask."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BadSkeletonError


@dataclass(frozen=True)
class SkeletonModel:
    """A named joint hierarchy.

    Attributes
    ----------
    name : str
        "kinect20", "openni17", "hand21", or a generic name (e.g. a BVH file's).
    joints : tuple of str
        Joint names, in order.
    parents : tuple of int
        parents[i] is the index of joint i's parent, -1 for a root.
    unskinned : tuple of str
        Joints whose own frame moves no vertex of their file's skin (an unweighted spine link, an IK
        helper); empty when the source has no skin to tell.
    """

    name: str
    joints: tuple[str, ...]
    parents: tuple[int, ...]
    unskinned: tuple[str, ...] = ()

    def __post_init__(self):
        if len(self.joints) != len(self.parents):
            raise BadSkeletonError(
                f"skeleton model {self.name!r}: {len(self.joints)} joints but {len(self.parents)} parents")
        for i, p in enumerate(self.parents):
            if p >= len(self.joints) or p < -1 or p == i:
                raise BadSkeletonError(f"skeleton model {self.name!r}: joint {self.joints[i]!r} has parent {p}")

    @property
    def bones(self) -> np.ndarray:
        """(B, 2) int32: (parent, child) joint index pairs."""
        pairs = [(p, c) for c, p in enumerate(self.parents) if p >= 0]
        return np.array(pairs, dtype=np.int32).reshape(-1, 2)

    @property
    def skinning_bones(self) -> np.ndarray:
        """(B,) bool per row of `bones`: the bone turns with a joint that moves skin in the source (its parent
        joint is not `unskinned`); all True when the source does not tell."""
        still = set(self.unskinned)
        return np.array([self.joints[p] not in still for p, _ in self.bones], dtype=bool)

    def index(self, joint: str) -> int:
        try:
            return self.joints.index(joint)
        except ValueError:
            raise BadSkeletonError(f"skeleton model {self.name!r} has no joint {joint!r}") from None


def _model(name: str, spec: list[tuple[str, str | None]]) -> SkeletonModel:
    joints = tuple(j for j, _ in spec)
    parents = tuple(-1 if p is None else joints.index(p) for _, p in spec)
    return SkeletonModel(name, joints, parents)


KINECT20 = _model("kinect20", [
    ("HipCenter", None), ("Spine", "HipCenter"), ("ShoulderCenter", "Spine"), ("Head", "ShoulderCenter"),
    ("ShoulderLeft", "ShoulderCenter"), ("ElbowLeft", "ShoulderLeft"), ("WristLeft", "ElbowLeft"),
    ("HandLeft", "WristLeft"),
    ("ShoulderRight", "ShoulderCenter"), ("ElbowRight", "ShoulderRight"), ("WristRight", "ElbowRight"),
    ("HandRight", "WristRight"),
    ("HipLeft", "HipCenter"), ("KneeLeft", "HipLeft"), ("AnkleLeft", "KneeLeft"), ("FootLeft", "AnkleLeft"),
    ("HipRight", "HipCenter"), ("KneeRight", "HipRight"), ("AnkleRight", "KneeRight"),
    ("FootRight", "AnkleRight"),
])

OPENNI17 = _model("openni17", [
    ("Torso", None), ("Neck", "Torso"), ("Head", "Neck"),
    ("LeftCollar", "Neck"), ("LeftShoulder", "LeftCollar"), ("LeftElbow", "LeftShoulder"),
    ("LeftWrist", "LeftElbow"),
    ("RightCollar", "Neck"), ("RightShoulder", "RightCollar"), ("RightElbow", "RightShoulder"),
    ("RightWrist", "RightElbow"),
    ("LeftHip", "Torso"), ("LeftKnee", "LeftHip"), ("LeftFoot", "LeftKnee"),
    ("RightHip", "Torso"), ("RightKnee", "RightHip"), ("RightFoot", "RightKnee"),
])

# MediaPipe HandLandmarker's 21 landmarks in its order: the wrist, then four joints per finger from the palm
# out; each finger is a chain hanging from the wrist, so the hand has 20 bones (5 of them across the palm).
FINGER_JOINTS = {"thumb": ("thumb_cmc", "thumb_mcp", "thumb_ip", "thumb_tip"),
           "index": ("index_mcp", "index_pip", "index_dip", "index_tip"),
           "middle": ("middle_mcp", "middle_pip", "middle_dip", "middle_tip"),
           "ring": ("ring_mcp", "ring_pip", "ring_dip", "ring_tip"),
           "little": ("pinky_mcp", "pinky_pip", "pinky_dip", "pinky_tip")}
HAND21 = _model("hand21", [("wrist", None)] + [(joint, chain[k - 1] if k else "wrist")
                                                for chain in FINGER_JOINTS.values() for k, joint in enumerate(chain)])

MODELS = {m.name: m for m in (KINECT20, OPENNI17, HAND21)}


@dataclass(frozen=True, eq=False)
class Skeleton:
    """One frame of a tracked skeleton, in metres, +Y up.

    Attributes
    ----------
    model : SkeletonModel
    positions : (J, 3) float64
        Joint positions; rows of untracked joints may hold anything (NaN included).
    tracked : (J,) bool
        False where the tracker lost the joint; a non-finite position counts as untracked too.
    bone_frames : (J, 3, 3) float64 or None
        Per joint, the world rotation of the bone that carries it (its parent joint's frame: the source's own
        rotation, twist included) where the source has joint rotations (BVH, glTF); NaN for joints without
        one; None for position-only sources (a camera).
    """

    model: SkeletonModel
    positions: np.ndarray
    tracked: np.ndarray
    bone_frames: np.ndarray | None = None

    def __post_init__(self):
        pos = np.asarray(self.positions, dtype=np.float64)
        j = len(self.model.joints)
        if pos.shape != (j, 3):
            raise BadSkeletonError(
                f"skeleton {self.model.name!r}: positions must be ({j}, 3), got {pos.shape}")
        tracked = np.asarray(self.tracked, dtype=bool)
        if tracked.shape != (j,):
            raise BadSkeletonError(f"skeleton {self.model.name!r}: tracked must be ({j},), got {tracked.shape}")
        tracked = tracked & np.isfinite(pos).all(axis=1)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "tracked", tracked)
        if self.bone_frames is not None:
            rot = np.asarray(self.bone_frames, dtype=np.float64)
            if rot.shape != (j, 3, 3):
                raise BadSkeletonError(
                    f"skeleton {self.model.name!r}: bone_frames must be ({j}, 3, 3), got {rot.shape}")
            object.__setattr__(self, "bone_frames", rot)

    @staticmethod
    def from_positions(model: SkeletonModel, positions) -> "Skeleton":
        pos = np.asarray(positions, dtype=np.float64)
        return Skeleton(model, pos, np.isfinite(pos).all(axis=1) if pos.ndim == 2 else np.zeros(0, bool))

    def transformed(self, scale: float = 1.0, rotation: np.ndarray | None = None,
                    translation=(0.0, 0.0, 0.0)) -> "Skeleton":
        """The same frame under x -> scale * rotation @ x + translation."""
        r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        return Skeleton(self.model, scale * self.positions @ r.T + np.asarray(translation, dtype=np.float64),
                        self.tracked, None if self.bone_frames is None else r @ self.bone_frames)

    @property
    def height(self) -> float:
        """Vertical extent of the tracked joints (0 when fewer than two are tracked)."""
        y = self.positions[self.tracked, 1]
        return float(y.max() - y.min()) if y.size >= 2 else 0.0
