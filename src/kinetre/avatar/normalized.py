"""An avatar's retargeted motion on the normalised humanoid that VMC and VRM receivers animate.

A normalised humanoid (Unity's Mecanim muscle space, VRM 1.0's and three-vrm's "normalized" bones) rests in
the T-pose with every rotation identity: legs down, spine up, arms out sideways, facing +Z with its left on
+X (VRM 1.0's frame; right-handed, +Y up). So for each bone b its world rotation relative to the T-pose is

    R_T(b) = R(b) · C(b),

R(b) the retargeted world rotation relative to the avatar's bind pose (`AvatarMotion.rotations`) and C(b) the
smallest rotation taking b's T-pose direction to its bind direction (an A-posed avatar has C ≠ I at the
arms; bones without a defined direction, hands, feet, head, take their parent's). The local rotation of b is
R_T(parent)ᵀ · R_T(b), parent being the nearest bone of this set above it in the humanoid hierarchy, so a
receiver that leaves the bones in between (chest, shoulders) at rest reproduces every world rotation.

The T-pose itself: bone b sits at its parent's T-pose place plus C(parent)ᵀ · (bind offset), i.e. the bind
offsets turned into the T-pose, the hips at their bind place; heights are measured from the lowest joint of
the bind pose (the floor), so the hips' height is the leg length a receiver scales root motion by.

Fingers (`FINGER_BONES`, given a `fingers.FingerMap`) follow the same rule: the T-pose of VRM 1.0 has the four
fingers straight along the arm (±X) and the thumb level, halfway between the arm and +Z; each finger bone's
C(b) takes that direction to the bone's bind direction (towards the next joint of its chain).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BadAvatarError
from ..rotation import minimal_rotations
from ..skeleton.mediapipe import FINGERS
from .bonemap import BoneMap
from .fingers import FingerMap
from .retarget import AvatarMotion, RetargetPlan

# Unity HumanBodyBones name -> (Kinect-20 joint playing it, nearest parent of this set, T-pose direction or None).
# VRM 1.0 names the same bones in lower camel case (`vrm_name`).
BONES = {
    "Hips": ("HipCenter", None, None),
    "Spine": ("Spine", "Hips", (0.0, 1.0, 0.0)),
    "Neck": ("ShoulderCenter", "Spine", (0.0, 1.0, 0.0)),
    "Head": ("Head", "Neck", None),
    "LeftUpperArm": ("ShoulderLeft", "Spine", (1.0, 0.0, 0.0)),
    "LeftLowerArm": ("ElbowLeft", "LeftUpperArm", (1.0, 0.0, 0.0)),
    "LeftHand": ("WristLeft", "LeftLowerArm", None),
    "RightUpperArm": ("ShoulderRight", "Spine", (-1.0, 0.0, 0.0)),
    "RightLowerArm": ("ElbowRight", "RightUpperArm", (-1.0, 0.0, 0.0)),
    "RightHand": ("WristRight", "RightLowerArm", None),
    "LeftUpperLeg": ("HipLeft", "Hips", (0.0, -1.0, 0.0)),
    "LeftLowerLeg": ("KneeLeft", "LeftUpperLeg", (0.0, -1.0, 0.0)),
    "LeftFoot": ("AnkleLeft", "LeftLowerLeg", None),
    "LeftToes": ("FootLeft", "LeftFoot", None),
    "RightUpperLeg": ("HipRight", "Hips", (0.0, -1.0, 0.0)),
    "RightLowerLeg": ("KneeRight", "RightUpperLeg", (0.0, -1.0, 0.0)),
    "RightFoot": ("AnkleRight", "RightLowerLeg", None),
    "RightToes": ("FootRight", "RightFoot", None),
}


# Unity's finger bones, palm out, of each `skeleton.mediapipe.FINGERS` finger -> (parent, T-pose direction)
FINGER_PARTS = ("Proximal", "Intermediate", "Distal")
FINGER_BONES = {}
for _side, _x in (("Left", 1.0), ("Right", -1.0)):
    for _finger in FINGERS:
        _along = (_x / np.sqrt(2.0), 0.0, 1.0 / np.sqrt(2.0)) if _finger == "thumb" else (_x, 0.0, 0.0)
        _parent = f"{_side}Hand"
        for _part in FINGER_PARTS:
            FINGER_BONES[f"{_side}{_finger.title()}{_part}"] = (_parent, _along)
            _parent = f"{_side}{_finger.title()}{_part}"
# every bone a normalised motion may hold -> its parent in it (None for the hips)
PARENTS = {b: parent for b, (_, parent, _) in BONES.items()} | {b: parent for b, (parent, _) in FINGER_BONES.items()}


def finger_bone(side: int, finger: str, k: int) -> str:
    """Unity's name of bone k (0 at the palm) of a finger (`skeleton.mediapipe.FINGERS` key) on side 0 (left)
    or 1 (right)."""
    return f"{('Left', 'Right')[side]}{finger.title()}{FINGER_PARTS[k]}"


def vrm_name(bone: str) -> str:
    """Unity's HumanBodyBones name -> VRM 1.0's humanoid bone name ("LeftUpperArm" -> "leftUpperArm")."""
    return bone[0].lower() + bone[1:]


@dataclass(frozen=True, eq=False)
class NormalizedMotion:
    """Retargeted frames on the normalised humanoid (right-handed, +Y up, facing +Z, the avatar's units).

    Attributes
    ----------
    bones : tuple of str, (B,)
        Unity HumanBodyBones names, parents before children (`PARENTS` gives each one's parent).
    rest : (B, 3) float64
        T-pose offset of each bone from its parent (the hips': their place above the floor).
    hips : (T, 3) float64
        The hips' place per frame, above the floor.
    rotations : (T, B, 3, 3) float64
        Local rotation of each bone relative to the T-pose (the hips': their world rotation).
    """

    bones: tuple
    rest: np.ndarray
    hips: np.ndarray
    rotations: np.ndarray

    def __len__(self) -> int:
        return int(self.rotations.shape[0])

    def parent(self, k: int) -> int:
        """Index of bone k's parent in `bones`, -1 for the hips."""
        p = PARENTS[self.bones[k]]
        return -1 if p is None else self.bones.index(p)


def normalized_motion(plan: RetargetPlan, bonemap: BoneMap, motion: AvatarMotion,
                      fingers: FingerMap | None = None) -> NormalizedMotion:
    """The module docstring's local rotations and T-pose for every frame of `motion`; with `fingers`, also the
    finger bones of the chains it holds (on a side whose hand bone maps)."""
    a = plan.align                                       # Kinetre facing (+Z) -> the avatar's
    names = tuple(b for b, (kj, _, _) in BONES.items() if kj in bonemap.joints)
    if not names or names[0] != "Hips":
        raise BadAvatarError("the avatar's bone map has no hips (HipCenter), so it has no humanoid root")
    joint = {b: bonemap.joints[BONES[b][0]] for b in names}
    floor = np.array([0.0, float(plan.bind_positions[:, 1].min()), 0.0])
    correction, bind, rest = {}, {}, {}
    for b in names:
        kj, parent, tpose = BONES[b]
        j = joint[b]
        if tpose is not None and plan.aim_from[j] >= 0:
            correction[b] = minimal_rotations(np.array(tpose), a.T @ plan.rest_aim[j])
        else:
            correction[b] = correction.get(parent, np.eye(3)) if parent else np.eye(3)
        above = plan.bind_positions[joint[parent]] if parent else floor
        bind[b] = a.T @ (plan.bind_positions[j] - above)
        rest[b] = bind[b] if parent is None else correction[parent].T @ bind[b]
    if fingers:
        names += _finger_bones(plan, fingers, names, joint, correction, bind, rest)
    world = {b: a.T @ motion.rotations[:, joint[b]] @ a @ correction[b] for b in names}   # R_T, facing +Z
    rotations = np.zeros((len(motion), len(names), 3, 3))
    for k, b in enumerate(names):
        parent = PARENTS[b]
        rotations[:, k] = world[b] if parent is None else np.swapaxes(world[parent], 1, 2) @ world[b]
    hips = (motion.positions[:, joint[names[0]]] - floor) @ a
    return NormalizedMotion(names, np.array([rest[b] for b in names]), hips, rotations)


def _finger_bones(plan, fingers: FingerMap, names, joint, correction, bind, rest) -> tuple:
    """Add each finger bone's joint, C(b), bind and T-pose offsets (in place); the bones' names, palm out."""
    a, p = plan.align, plan.bind_positions
    added = []
    for (side, finger), chain in sorted(fingers.chains.items()):
        hand = f"{('Left', 'Right')[side]}Hand"
        if hand not in names:
            continue
        parent = hand
        for k, j in enumerate(chain[:len(FINGER_PARTS)]):
            b = finger_bone(side, finger, k)
            along = np.array(FINGER_BONES[b][1])
            aim = a.T @ (p[chain[k + 1]] - p[j]) if k + 1 < len(chain) else None
            if aim is not None and np.linalg.norm(aim) > 1e-12:
                correction[b] = minimal_rotations(along, aim / np.linalg.norm(aim))
            else:                                    # a tip without a child: the bone before it
                correction[b] = correction[parent] if parent != hand else np.eye(3)
            joint[b] = j
            bind[b] = a.T @ (p[j] - p[joint[parent]])
            rest[b] = correction[parent].T @ bind[b]
            added.append(b)
            parent = b
    return tuple(added)
