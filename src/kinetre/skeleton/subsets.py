"""Named joint subsets ("left arm", "upper body", …) that choose which joints drive the mesh (KinÊtre paper,
"Constraints")."""
from __future__ import annotations

import numpy as np

from ..errors import BadSkeletonError
from .models import KINECT20, OPENNI17, SkeletonModel

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

_OPENNI_FROM_KINECT = {
    "HipCenter": "Torso", "Spine": "Torso", "ShoulderCenter": "Neck", "Head": "Head",
    "ShoulderLeft": "LeftShoulder", "ElbowLeft": "LeftElbow", "WristLeft": "LeftWrist", "HandLeft": "LeftWrist",
    "ShoulderRight": "RightShoulder", "ElbowRight": "RightElbow", "WristRight": "RightWrist",
    "HandRight": "RightWrist", "HipLeft": "LeftHip", "KneeLeft": "LeftKnee", "AnkleLeft": "LeftFoot",
    "FootLeft": "LeftFoot", "HipRight": "RightHip", "KneeRight": "RightKnee", "AnkleRight": "RightFoot",
    "FootRight": "RightFoot",
}


def subset_names() -> tuple[str, ...]:
    return tuple(SUBSETS)


def subset_mask(model: SkeletonModel, subset: str | list[str] | tuple[str, ...] | None) -> np.ndarray:
    """(J,) bool mask of the joints of `model` in `subset`.

    `subset` is a name from SUBSETS ("left arm", …), a list of names and/or joint names (a user
    list, e.g. ["HipCenter", "right arm"]), or None for the whole body. A generic model (BVH,
    animal) accepts its own joint names, and "whole body".
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
        if key in ("whole body", "all", "body"):
            mask[:] = True
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
            f"unknown joint subset {item!r}: expected one of {', '.join(SUBSETS)} or a joint of {model.name!r}")
    return mask
