"""Named joint subsets ("left arm", "upper body", …; a hand's "index", "fingers", …) that choose which joints
drive the mesh (KinÊtre paper, "Constraints")."""
from __future__ import annotations

import numpy as np

from ..errors import BadSkeletonError
from .models import FINGER_JOINTS, HAND21, KINECT20, OPENNI17, SkeletonModel

# Kinect-20 names; other models are mapped through _ALIASES below.
_LEFT_ARM = ("ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft")
_RIGHT_ARM = ("ShoulderRight", "ElbowRight", "WristRight", "HandRight")
_LEFT_LEG = ("HipLeft", "KneeLeft", "AnkleLeft", "FootLeft")
_RIGHT_LEG = ("HipRight", "KneeRight", "AnkleRight", "FootRight")
_SPINE = ("HipCenter", "Spine", "ShoulderCenter", "Head")

SUBSETS: dict[str, tuple[str, ...]] = {
    "left arm": _LEFT_ARM,
    "right arm": _RIGHT_ARM,
    "arms": _LEFT_ARM + _RIGHT_ARM,
    "left leg": _LEFT_LEG,
    "right leg": _RIGHT_LEG,
    "legs": _LEFT_LEG + _RIGHT_LEG,
    "spine": _SPINE,
    "upper body": _SPINE[1:] + _LEFT_ARM + _RIGHT_ARM,
    "lower body": ("HipCenter",) + _LEFT_LEG + _RIGHT_LEG,
    "whole body": KINECT20.joints,
}

# A hand (HAND21): each finger by name (the little finger is also MediaPipe's "pinky"), every finger, the palm
# (the wrist and the finger bases).
HAND_SUBSETS: dict[str, tuple[str, ...]] = {
    **FINGER_JOINTS, "pinky": FINGER_JOINTS["little"],
    "fingers": tuple(j for chain in FINGER_JOINTS.values() for j in chain),
    "palm": ("wrist",) + tuple(chain[0] for chain in FINGER_JOINTS.values()),
}

_OPENNI_FROM_KINECT = {
    "HipCenter": "Torso", "Spine": "Torso", "ShoulderCenter": "Neck", "Head": "Head",
    "ShoulderLeft": "LeftShoulder", "ElbowLeft": "LeftElbow", "WristLeft": "LeftWrist", "HandLeft": "LeftWrist",
    "ShoulderRight": "RightShoulder", "ElbowRight": "RightElbow", "WristRight": "RightWrist",
    "HandRight": "RightWrist", "HipLeft": "LeftHip", "KneeLeft": "LeftKnee", "AnkleLeft": "LeftFoot",
    "FootLeft": "LeftFoot", "HipRight": "RightHip", "KneeRight": "RightKnee", "AnkleRight": "RightFoot",
    "FootRight": "RightFoot",
}


def subset_names(model: SkeletonModel = KINECT20) -> tuple[str, ...]:
    """The subset names `subset_mask` takes for `model`."""
    return tuple(HAND_SUBSETS if model.name == HAND21.name else SUBSETS)


def subset_mask(model: SkeletonModel, subset: str | list[str] | tuple[str, ...] | None) -> np.ndarray:
    """(J,) bool mask of the joints of `model` in `subset`.

    `subset` is a name from SUBSETS ("left arm", …), a list of names and/or joint names (a user
    list, e.g. ["HipCenter", "right arm"]), or None for the whole body. A hand takes the names of
    HAND_SUBSETS ("index", "fingers", ...) instead. A generic model (BVH, animal) accepts its own joint
    names, and "whole body".
    """
    j = len(model.joints)
    if subset is None:
        return np.ones(j, dtype=bool)
    items = [subset] if isinstance(subset, str) else list(subset)
    mask = np.zeros(j, dtype=bool)
    for item in items:
        if item in model.joints:  # an exact joint name wins over a subset ("Spine" vs "spine")
            mask[model.joints.index(item)] = True
            continue
        key = item.strip().lower()
        if key in ("whole body", "all", "body", "whole hand", "hand"):
            mask[:] = True
            continue
        if model.name == HAND21.name and key in HAND_SUBSETS:
            mask[[model.joints.index(n) for n in HAND_SUBSETS[key]]] = True
            continue
        if key in SUBSETS:
            names = SUBSETS[key]
            if model.name == OPENNI17.name:
                names = tuple(_OPENNI_FROM_KINECT[n] for n in names)
            found = [model.joints.index(n) for n in names if n in model.joints]
            if not found:
                raise BadSkeletonError(
                    f"subset {item!r} names no joint of skeleton {model.name!r}; use its joint names")
            mask[found] = True
            continue
        lowered = [n.lower() for n in model.joints]
        if key in lowered:
            mask[lowered.index(key)] = True
            continue
        raise BadSkeletonError(
            f"unknown joint subset {item!r}: expected one of {', '.join(subset_names(model))} or a joint of "
            f"{model.name!r}")
    return mask
