"""Which avatar joints are the fingers: per hand and finger, the chain of joints from the palm out.

Found in order: the VRM humanoid's finger bones (VRM 1.0 `leftThumbMetacarpal`, VRM 0.x
`leftThumbProximal`, ... `leftLittleDistal`); else, below each mapped elbow (a rig may hang its palm bones
straight on the forearm), the joints whose name holds a finger's word (thumb; index, pointer; middle, mid;
ring; pinky, little, small), each the child of the one before. Side comes from the arm the chain hangs
under, so any naming of sides works.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..skeleton.mediapipe import FINGERS
from .bonemap import BoneMap
from .load import Avatar

SIDES = ("Left", "Right")
_WORDS = {"thumb": ("thumb",), "index": ("index", "pointer"), "middle": ("middle", "mid"),
          "ring": ("ring",), "little": ("pinky", "little", "small")}
_VRM_PARTS = ("Metacarpal", "Proximal", "Intermediate", "Distal")


@dataclass(frozen=True)
class FingerMap:
    """chains[(side, finger)] = joint indices from the palm out (side 0 left, 1 right; finger a key of
    `kinetre.skeleton.mediapipe.FINGERS`). Fingers the avatar lacks are absent."""

    chains: dict

    def __bool__(self) -> bool:
        return bool(self.chains)


def map_fingers(avatar: Avatar, bonemap: BoneMap) -> FingerMap:
    """The avatar's finger chains (empty when it has no finger joints)."""
    chains = {}
    for side, s in enumerate(SIDES):
        for finger in FINGERS:
            vrm = [avatar.vrm_bones[f"{s.lower()}{finger.title()}{part}"] for part in _VRM_PARTS
                   if f"{s.lower()}{finger.title()}{part}" in avatar.vrm_bones]
            arm = bonemap.joints.get(f"Elbow{s}", bonemap.joints.get(f"Wrist{s}"))
            chain = vrm or _named_chain(avatar, arm, finger)
            if chain:
                chains[side, finger] = tuple(int(j) for j in chain)
    return FingerMap(chains)


def _named_chain(avatar: Avatar, arm: int | None, finger: str) -> list[int]:
    if arm is None:
        return []
    words = _WORDS[finger]
    found = []
    for j, name in enumerate(avatar.joint_names):
        depth = _depth_below(avatar.joint_parents, j, arm)
        if depth is None:
            continue
        tokens = re.findall(r"[a-z]+", re.sub(r"([a-z])([A-Z])", r"\1 \2", name).lower())
        if any(t.startswith(w) for t in tokens for w in words):  # "Index1", "pinky_01", "ThumbFinger"
            found.append((depth, j))
    found.sort()
    # one chain: each joint the child of the previous one
    chain: list[int] = []
    for _, j in found:
        if not chain or avatar.joint_parents[j] == chain[-1]:
            chain.append(j)
    return chain


def _depth_below(parents: np.ndarray, j: int, ancestor: int) -> int | None:
    depth, k = 0, j
    while k >= 0:
        if k == ancestor:
            return depth if depth > 0 else None
        k, depth = int(parents[k]), depth + 1
    return None
