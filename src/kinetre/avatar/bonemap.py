"""Which avatar joint plays which Kinect-20 joint: the skeleton mapper (`kinetre.skeleton.humanoid_map`:
VRM humanoid, names, topology, bind-pose geometry) on the avatar's skin joints; a saved map (JSON next to the
avatar) overrides it. The avatar is then driven by the joints that map.

Other tracked skeletons reach the avatar through Kinect-20: OpenNI-17 by `kinect_from_openni`, MediaPipe-33
by `kinetre.skeleton.mediapipe.kinect_from_mediapipe`.
"""
from __future__ import annotations

import json
import os

import numpy as np

from ..errors import BadAvatarError, BadMotionError
from ..skeleton.humanoid_map import (REQUIRED, UP, HumanoidMap, kinect_frames, map_humanoid, not_humanoid, parse_table,
                                     table_of, upright_problems)
from ..skeleton.models import KINECT20, OPENNI17
from ..skeleton.tips import part_end, part_tips
from .load import Avatar

__all__ = ["REQUIRED", "UP", "BoneMap", "map_path", "map_bones", "auto_map", "can_drive", "check_humanoid", "describe",
           "mapping_skeleton",
           "write_map", "read_map", "parse_map", "kinect_from_openni"]

# An avatar's map: Kinect joint -> skin joint index (`joints`), how each was found, the facing.
BoneMap = HumanoidMap


def map_path(avatar_path: str) -> str:
    """Where a corrected map is saved: next to the avatar, `<file>.kinetre-map.json`."""
    return os.fspath(avatar_path) + ".kinetre-map.json"


def map_bones(avatar: Avatar, saved: str | None = None) -> BoneMap:
    """Map the avatar's joints to Kinect-20 and check that it is an upright humanoid.

    The avatar is driven by what maps; the joints it lacks (`BoneMap.missing`, e.g. a chibi without elbows)
    follow their parents.

    Parameters
    ----------
    saved : str, optional
        A map JSON file; by default `map_path(avatar.source)` when it exists.

    Raises
    ------
    BadAvatarError
        No root and no limb chain maps (the message lists what is missing and how to fix it), or the
        skeleton is not an upright biped (e.g. a quadruped: the message points to possession).
    """
    bonemap = auto_map(avatar, saved)
    name = os.path.basename(avatar.source)
    if not can_drive(bonemap):
        raise BadAvatarError(
            f"{avatar.source}: cannot map the skeleton to a body: no joint found for "
            f"{', '.join(bonemap.missing)} (mapped: {_describe(avatar, bonemap)}); if it is a humanoid, name the "
            f"joints in {os.path.basename(map_path(name))} next to it (the studio's avatar map editor writes "
            f"it); a non-humanoid is brought to life by possession: kinetre animate {name} --motion ...")
    check_humanoid(avatar, bonemap)
    return bonemap


def can_drive(bonemap: BoneMap) -> bool:
    """Enough maps to drive the avatar: the hips, a joint up the torso and one limb chain to turn the body by
    (the joints that do not map follow their parents)."""
    m = bonemap.joints
    return bonemap.drivable and "HipCenter" in m and ("ShoulderCenter" in m or "Head" in m) and bool(bonemap.limbs)


def auto_map(avatar: Avatar, saved: str | None = None) -> BoneMap:
    """The map as found (saved file, VRM, names, topology, geometry), possibly incomplete (`BoneMap.missing`).
    Its skeleton is `mapping_skeleton`'s: the skin joints, then the part tips."""
    saved = saved if saved is not None else map_path(avatar.source)
    fixed = read_map(saved, avatar) if os.path.exists(saved) else None
    names, parents, rest, tips = mapping_skeleton(avatar)
    return map_humanoid(names, parents, rest, avatar.vrm_bones, fixed, tips=tips)


def mapping_skeleton(avatar: Avatar) -> tuple[tuple[str, ...], tuple[int, ...], np.ndarray, int]:
    """(names, parents, bind positions, tips): the skin joints, then a tip where each childless joint's
    skinned part ends, for those whose part lies off them (`kinetre.skeleton.tips`, as a motion file's
    skeleton gets them)."""
    n = len(avatar.joints)
    sums, mass, mostly = np.zeros((n, 3)), np.zeros(n), [[] for _ in range(n)]
    for prim in avatar.primitives:
        # each vertex in its joints' own bind frames (IBM · v), as the glTF reader of motion files does
        local = np.einsum("vkab,vb->vka", avatar.inverse_bind[prim.joints][..., :3, :3], prim.positions) + \
            avatar.inverse_bind[prim.joints][..., :3, 3]
        np.add.at(sums, prim.joints.ravel(), (prim.weights[..., None] * local).reshape(-1, 3))
        np.add.at(mass, prim.joints.ravel(), prim.weights.ravel())
        for v, k in zip(*np.nonzero(prim.weights >= 0.5)):
            mostly[prim.joints[v, k]].append(local[v, k])
    bind = avatar.bind_world

    def world(j, c):
        return bind[j, :3, :3] @ c + bind[j, :3, 3]

    centres = {j: world(j, sums[j] / mass[j]) for j in range(n) if mass[j] > 0}
    names, parents, rest = tuple(avatar.joint_names), tuple(int(q) for q in avatar.joint_parents), avatar.bind_positions
    ends = part_tips(names, parents, rest, centres)
    if not ends:
        return names, parents, rest, 0
    tips = [world(k, part_end(sums[k] / mass[k], np.array(mostly[k]).reshape(-1, 3))) for k, _, _ in ends]
    return (names + tuple(name for _, name, _ in ends), parents + tuple(k for k, _, _ in ends),
            np.vstack([rest, tips]), len(ends))


def check_humanoid(avatar: Avatar, bonemap: BoneMap) -> None:
    """Refuse skeletons that are not upright bipeds in their bind pose: the torso (hips -> shoulder centre)
    within 45 degrees of vertical, both legs (hip -> ankle) pointing down."""
    problems = upright_problems(bonemap, avatar.bind_positions, UP)
    if problems:
        raise BadAvatarError(f"{avatar.source}: not an upright humanoid ({'; '.join(problems)}), so it cannot be "
                             f"driven as an avatar; bring it to life by possession instead: kinetre animate "
                             f"{os.path.basename(avatar.source)} --motion ...")


def describe(avatar: Avatar, bonemap: BoneMap) -> str:
    """One line: Kinect joint <- avatar joint (how), then what does not map, for `kinetre avatar` and the studio."""
    text = _describe(avatar, bonemap)
    derived = [kj for kj in bonemap.missing if kj in bonemap.derived]
    lost = [kj for kj in bonemap.missing if kj not in bonemap.derived]
    return text + (f"; derived (from where parts end, or between joints): {', '.join(derived)}" if derived else "") + \
        (f"; not mapped: {', '.join(lost)}" if lost else "")


def _describe(avatar, bonemap):
    return ", ".join(f"{kj}<-{avatar.joint_names[j]} ({bonemap.how[kj]})"
                     for kj, j in sorted(bonemap.joints.items(), key=lambda kv: KINECT20.index(kv[0]))) or "nothing"


# ---- JSON -------------------------------------------------------------------------------------------

def write_map(path: str, avatar: Avatar, joints: dict) -> None:
    """Save Kinect joint -> avatar joint as JSON (joint names where unique, else "#<skin index>")."""
    try:
        with open(path, "w", encoding="utf-8") as f:
            json.dump({"avatar": os.path.basename(avatar.source), "kinect20": table_of(joints, avatar.joint_names)},
                      f, indent=1)
            f.write("\n")
    except OSError as e:
        raise BadAvatarError(f"{path}: cannot write the avatar map ({e.strerror or e})") from None


def read_map(path: str, avatar: Avatar) -> dict:
    """Kinect joint -> joint index from a map JSON (see `write_map`); names or "#index" or ints."""
    try:
        with open(path, encoding="utf-8") as f:
            body = json.load(f)
    except (OSError, ValueError) as e:
        raise BadAvatarError(f"{path}: not a readable avatar map ({e})") from None
    table = body.get("kinect20") if isinstance(body, dict) else None
    if not isinstance(table, dict):
        raise BadAvatarError(f"{path}: an avatar map needs a \"kinect20\" object (Kinect joint -> avatar joint)")
    return parse_map(table, avatar, path)


def parse_map(table: dict, avatar: Avatar, where: str) -> dict:
    return parse_table(table, avatar.joint_names, where, BadAvatarError)


# ---- other source skeletons ---------------------------------------------------------------------------

_FROM_OPENNI = {"HipCenter": ("LeftHip", "RightHip"), "Spine": ("Torso",), "ShoulderCenter": ("Neck",),
                "Head": ("Head",), "ShoulderLeft": ("LeftShoulder",), "ElbowLeft": ("LeftElbow",),
                "WristLeft": ("LeftWrist",), "ShoulderRight": ("RightShoulder",), "ElbowRight": ("RightElbow",),
                "WristRight": ("RightWrist",), "HipLeft": ("LeftHip",), "KneeLeft": ("LeftKnee",),
                "AnkleLeft": ("LeftFoot",), "HipRight": ("RightHip",), "KneeRight": ("RightKnee",),
                "AnkleRight": ("RightFoot",)}


def kinect_from_openni(positions: np.ndarray, tracked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenNI-17 frames (..., 17, 3) -> Kinect-20 (..., 20, 3) and tracked (..., 20); the hands and feet,
    which OpenNI lacks, are left untracked (the avatar's hands and feet then follow the forearms and shins)."""
    positions = np.asarray(positions, dtype=np.float64)
    tracked = np.asarray(tracked, dtype=bool)
    out = np.full(positions.shape[:-2] + (len(KINECT20.joints), 3), np.nan)
    seen = np.zeros(positions.shape[:-2] + (len(KINECT20.joints),), dtype=bool)
    for kj, src in _FROM_OPENNI.items():
        idx = [OPENNI17.index(s) for s in src]
        out[..., KINECT20.index(kj), :] = positions[..., idx, :].mean(axis=-2)
        seen[..., KINECT20.index(kj)] = tracked[..., idx].all(axis=-1)
    return out, seen & np.isfinite(out).all(axis=-1)


def kinect_take(take):
    """A take on Kinect-20: OpenNI-17 takes converted, a take of another skeleton (a recorded take that kept
    its own bones) mapped by the skeleton mapper from its first frame; a non-human cannot drive an avatar."""
    from ..motion.source import Take
    if take.model.name == "kinect20":
        return take
    if take.model.name == "openni17":
        pos, tracked = kinect_from_openni(take.positions, take.tracked)
        return Take(KINECT20, pos, tracked, take.fps, take.source)
    rest = np.nan_to_num(take.positions[0])
    hmap = map_humanoid(take.model.joints, take.model.parents, rest)
    why = not_humanoid(hmap, rest)
    if why:
        raise BadMotionError(f"{take.source}: its skeleton ({take.model.name}) is not a humanoid ({why}), so it "
                             "cannot drive a humanoid avatar (name the joints like Mixamo/CMU/Kinect, or possess a "
                             "mesh with it: kinetre animate)")
    pos, tracked = kinect_frames(hmap, np.nan_to_num(take.positions))
    lost = (~take.tracked).astype(np.float64) @ (hmap.weights() != 0).T.astype(np.float64) > 0   # a source lost
    return Take(KINECT20, pos, tracked & ~lost, take.fps, take.source)
