"""Which avatar joint plays which Kinect-20 joint: by the VRM humanoid, by name, then by the bind pose's
geometry; a saved map (JSON next to the avatar) overrides all three.

Names: Kinect-20/Mixamo/CMU/MocapBank spellings (the BVH reader's candidate lists), then words in the name
(side "L"/"Left"/"R"/"Right", part "UpperArm", "ForeArm", "Thigh", "Calf", "Toe"…, noise such as "mixamorig",
"J_Bip", "DEF" dropped), and numbered limb chains ("arm_joint_L_1..3", "leg_joint_R_1..5") assigned in
order along the limb.

Geometry (where names fail, e.g. a file whose joints have no names): the pelvis is the shallowest joint
with two child chains reaching down and one reaching up; up that chain, the chest is the first joint
with two child chains reaching out sideways (the arms), the rest going up being the neck and head. Along
a limb chain the two longest consecutive bones are the upper and lower limb (so clavicles, twist and
finger joints fall out). Left and right come from the facing, which the feet give (ankle → toe), else
glTF's +Z front.

Other tracked skeletons reach the avatar through Kinect-20: OpenNI-17 by `kinect_from_openni`, MediaPipe-33
by `kinetre.skeleton.mediapipe.kinect_from_mediapipe`.
"""
from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass

import numpy as np

from ..errors import BadAvatarError
from ..motion.bvh import _candidates, _key
from ..skeleton.models import KINECT20, OPENNI17
from .load import Avatar

# Needed to drive a body; the others (Spine, Head, hands, feet) are used when present.
REQUIRED = ("HipCenter", "ShoulderCenter", "ShoulderLeft", "ElbowLeft", "WristLeft", "ShoulderRight",
            "ElbowRight", "WristRight", "HipLeft", "KneeLeft", "AnkleLeft", "HipRight", "KneeRight", "AnkleRight")
UP = np.array([0.0, 1.0, 0.0])

_VRM = {"hips": "HipCenter", "spine": "Spine", "neck": "ShoulderCenter", "head": "Head",
        "leftUpperArm": "ShoulderLeft", "leftLowerArm": "ElbowLeft", "leftHand": "WristLeft",
        "leftMiddleProximal": "HandLeft", "rightUpperArm": "ShoulderRight", "rightLowerArm": "ElbowRight",
        "rightHand": "WristRight", "rightMiddleProximal": "HandRight", "leftUpperLeg": "HipLeft",
        "leftLowerLeg": "KneeLeft", "leftFoot": "AnkleLeft", "leftToes": "FootLeft", "rightUpperLeg": "HipRight",
        "rightLowerLeg": "KneeRight", "rightFoot": "AnkleRight", "rightToes": "FootRight"}
# words of a joint name (side and noise removed, joined) -> Kinect part ("" for torso joints: no side)
_PARTS = {"upperarm": "Shoulder", "uparm": "Shoulder", "arm": "Shoulder", "forearm": "Elbow",
          "lowerarm": "Elbow", "elbow": "Elbow", "hand": "Wrist", "wrist": "Wrist", "upperleg": "Hip",
          "upleg": "Hip", "thigh": "Hip", "lowerleg": "Knee", "leg": "Knee", "calf": "Knee", "shin": "Knee",
          "knee": "Knee", "foot": "Ankle", "ankle": "Ankle", "toe": "Foot", "toes": "Foot", "toebase": "Foot",
          "ball": "Foot", "hips": "HipCenter", "pelvis": "HipCenter", "spine": "Spine", "neck": "ShoulderCenter",
          "head": "Head"}
_NOISE = {"mixamorig", "j", "bip", "b", "def", "org", "mch", "joint", "jnt", "bone", "c", "cc", "base"}
_CHAIN = {"arm": ("Shoulder", "Elbow", "Wrist", "Hand"), "leg": ("Hip", "Knee", "Ankle", "Foot")}


@dataclass(frozen=True)
class BoneMap:
    """Kinect-20 joint -> avatar joint (index into `Avatar.joints`), how each was found, and the facing.

    Attributes
    ----------
    joints : dict str -> int
    how : dict str -> str
        "vrm", "name", "geometry" or "file" per mapped joint.
    facing : (3,) float64
        Horizontal unit vector the avatar faces in its bind pose (world).
    """

    joints: dict
    how: dict
    facing: np.ndarray

    @property
    def missing(self) -> tuple[str, ...]:
        return tuple(j for j in REQUIRED if j not in self.joints)


def map_path(avatar_path: str) -> str:
    """Where a corrected map is saved: next to the avatar, `<file>.kinetre-map.json`."""
    return os.fspath(avatar_path) + ".kinetre-map.json"


def map_bones(avatar: Avatar, saved: str | None = None) -> BoneMap:
    """Map the avatar's joints to Kinect-20 and check that it is an upright humanoid.

    Parameters
    ----------
    saved : str, optional
        A map JSON file; by default `map_path(avatar.source)` when it exists.

    Raises
    ------
    BadAvatarError
        The map cannot be completed (the message lists the missing Kinect joints and how to fix them) or
        the skeleton is not an upright biped (e.g. a quadruped: the message points to possession).
    """
    bonemap = auto_map(avatar, saved)
    name = os.path.basename(avatar.source)
    if bonemap.missing:
        raise BadAvatarError(
            f"{avatar.source}: cannot map the skeleton to a body: no joint found for "
            f"{', '.join(bonemap.missing)} (mapped: {_describe(avatar, bonemap)}); if it is a humanoid, name the "
            f"joints in {os.path.basename(map_path(name))} next to it (the studio's avatar map editor writes "
            f"it); a non-humanoid is brought to life by possession: kinetre animate {name} --motion ...")
    check_humanoid(avatar, bonemap)
    return bonemap


def auto_map(avatar: Avatar, saved: str | None = None) -> BoneMap:
    """The map as found (saved file, VRM, names, geometry), possibly incomplete (`BoneMap.missing`)."""
    p = avatar.bind_positions
    found: dict[str, int] = {}
    how: dict[str, str] = {}
    saved = saved if saved is not None else map_path(avatar.source)
    if os.path.exists(saved):
        for kj, j in read_map(saved, avatar).items():
            found[kj], how[kj] = j, "file"
    for bone, kj in _VRM.items():
        if bone in avatar.vrm_bones and kj not in found:
            found[kj], how[kj] = avatar.vrm_bones[bone], "vrm"
    if not avatar.vrm_bones:
        for kj, j in _by_name(avatar).items():
            if kj not in found and j not in found.values():
                found[kj], how[kj] = j, "name"
    if "HipLeft" in found and "HipRight" in found and "file" != how.get("HipCenter"):
        # the pelvis carries both legs: a "Hips" that does not (legs hung on a parent) is the lowest spine joint
        lca = _common_ancestor(avatar.joint_parents, found["HipLeft"], found["HipRight"])
        if lca >= 0 and found.get("HipCenter") != lca and not _is_ancestor(avatar.joint_parents, found.get(
                "HipCenter", -1), found["HipLeft"]):
            found["HipCenter"], how["HipCenter"] = lca, "geometry"
    if any(j not in found for j in REQUIRED) or "Spine" not in found or "Head" not in found:
        for kj, j in _by_geometry(avatar).items():
            if kj not in found and j not in found.values():
                found[kj], how[kj] = j, "geometry"
    return BoneMap(found, how, _facing(p, found))


def check_humanoid(avatar: Avatar, bonemap: BoneMap) -> None:
    """Refuse skeletons that are not upright bipeds in their bind pose: the torso (hips → shoulder centre)
    within 45° of vertical, both legs (hip → ankle) pointing down, the shoulders above the hips."""
    p, m = avatar.bind_positions, bonemap.joints
    name = os.path.basename(avatar.source)

    def angle(a, b, ref):
        v = p[m[b]] - p[m[a]]
        n = np.linalg.norm(v)
        return 180.0 if n < 1e-12 else float(np.degrees(np.arccos(np.clip(v @ ref / n, -1, 1))))

    torso = angle("HipCenter", "ShoulderCenter", UP)
    legs = [angle(f"Hip{s}", f"Ankle{s}", -UP) for s in ("Left", "Right")]
    problems = []
    if torso > 45:
        problems.append(f"its spine ({avatar.joint_names[m['HipCenter']]} -> "
                        f"{avatar.joint_names[m['ShoulderCenter']]}) is {torso:.0f} degrees from vertical")
    if max(legs) > 60:
        problems.append(f"its legs point {max(legs):.0f} degrees away from down")
    if problems:
        raise BadAvatarError(f"{avatar.source}: not an upright humanoid ({'; '.join(problems)}), so it cannot be "
                             f"driven as an avatar; bring it to life by possession instead: kinetre animate "
                             f"{name} --motion ...")


def describe(avatar: Avatar, bonemap: BoneMap) -> str:
    """One line: Kinect joint <- avatar joint (how), for `kinetre avatar` and the studio."""
    return _describe(avatar, bonemap)


def _describe(avatar, bonemap):
    return ", ".join(f"{kj}<-{avatar.joint_names[j]} ({bonemap.how[kj]})"
                     for kj, j in sorted(bonemap.joints.items(), key=lambda kv: KINECT20.index(kv[0]))) or "nothing"


# ---- JSON -------------------------------------------------------------------------------------------

def write_map(path: str, avatar: Avatar, joints: dict) -> None:
    """Save Kinect joint -> avatar joint as JSON (joint names where unique, else "#<skin index>")."""
    counts = {n: avatar.joint_names.count(n) for n in avatar.joint_names}
    body = {kj: avatar.joint_names[j] if counts[avatar.joint_names[j]] == 1 else f"#{j}"
            for kj, j in sorted(joints.items(), key=lambda kv: KINECT20.index(kv[0]))}
    try:
        with open(path, "w", encoding="utf-8") as f:
            json.dump({"avatar": os.path.basename(avatar.source), "kinect20": body}, f, indent=1)
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
    out = {}
    for kj, ref in table.items():
        if kj not in KINECT20.joints:
            raise BadAvatarError(f"{where}: {kj!r} is not a Kinect-20 joint ({', '.join(KINECT20.joints)})")
        if ref is None or ref == "":
            continue
        if isinstance(ref, int) or (isinstance(ref, str) and ref.startswith("#") and ref[1:].isdigit()):
            j = int(ref if isinstance(ref, int) else ref[1:])
            if not 0 <= j < len(avatar.joints):
                raise BadAvatarError(f"{where}: {kj}: joint #{j} is outside the avatar's {len(avatar.joints)} joints")
        elif isinstance(ref, str) and avatar.joint_names.count(ref) == 1:
            j = avatar.joint_names.index(ref)
        else:
            raise BadAvatarError(f"{where}: {kj}: the avatar has no single joint named {ref!r}")
        out[kj] = j
    return out


# ---- by name ------------------------------------------------------------------------------------------

def _tokens(name: str) -> list[str]:
    name = name.rsplit(":", 1)[-1]
    return [t.lower() for t in re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+", name)]


def _by_name(avatar: Avatar) -> dict:
    depth = _depths(avatar.joint_parents)
    keys = [_key(n) for n in avatar.joint_names]
    found: dict[str, int] = {}
    for kj in KINECT20.joints:                   # exact spellings first (Kinect, Mixamo, CMU, MocapBank)
        for c in _candidates(kj):
            hits = [j for j, k in enumerate(keys) if k == c and j not in found.values()]
            if hits:
                found[kj] = min(hits, key=lambda j: depth[j])
                break
    chains: dict[tuple[str, str], list[tuple[int, int]]] = {}
    words: dict[str, list[int]] = {}
    for j, name in enumerate(avatar.joint_names):
        toks = _tokens(name)
        side = ("Left" if {"left", "l"} & set(toks) else "Right" if {"right", "r"} & set(toks) else "")
        digits = [t for t in toks if t.isdigit()]
        rest = "".join(t for t in toks if not t.isdigit() and t not in _NOISE | {"left", "l", "right", "r"})
        if side and rest in _CHAIN and digits:
            chains.setdefault((side, rest), []).append((int(digits[0]), j))
            continue
        part = _PARTS.get(rest)
        if part is None:
            continue
        if part in ("HipCenter", "Spine", "ShoulderCenter", "Head"):
            if not side:
                words.setdefault(part, []).append(j)
        elif side:
            words.setdefault(part + side, []).append(j)
    for (side, limb), members in chains.items():
        for part, (_, j) in zip(_CHAIN[limb], sorted(members)):
            words.setdefault(part + side, []).insert(0, j)
    for kj, js in words.items():
        if kj not in found:
            free = [j for j in js if j not in found.values()]
            if free:
                found[kj] = min(free, key=lambda j: depth[j])
    return found


# ---- by geometry --------------------------------------------------------------------------------------

def _by_geometry(avatar: Avatar) -> dict:
    """The structural map of the module docstring; {} when no pelvis is found."""
    p = avatar.bind_positions
    parents = avatar.joint_parents
    n = len(p)
    children = [[c for c in range(n) if parents[c] == j] for j in range(n)]
    subtree = [_subtree(children, j) for j in range(n)]
    height = max(float(np.ptp(p[:, 1])), 1e-9)
    low = np.array([p[s, 1].min() for s in subtree])
    high = np.array([p[s, 1].max() for s in subtree])
    depth = _depths(parents)
    pelvis = legs = up = None
    for j in sorted(range(n), key=lambda j: depth[j]):
        down = [c for c in children[j] if low[c] < p[j, 1] - 0.12 * height]
        ups = [c for c in children[j] if high[c] > p[j, 1] + 0.12 * height and c not in down]
        if len(down) >= 2 and ups:
            pelvis, legs = j, sorted(down, key=lambda c: low[c])[:2]
            up = max(ups, key=lambda c: high[c])
            break
    if pelvis is None:
        return {}

    def reach(j, origin):
        d = p[subtree[j]] - p[origin]
        return float(np.hypot(d[:, 0], d[:, 2]).max())

    chest, arms, neck, j = None, [], None, up
    path = [up]
    while True:
        side = [c for c in children[j] if reach(c, j) > 0.15 * height]
        if len(side) >= 2:
            chest, arms = j, sorted(side, key=lambda c: -reach(c, j))[:2]
            rest = [c for c in children[j] if c not in arms]
            neck = max(rest, key=lambda c: high[c]) if rest else None
            break
        if not children[j]:
            break
        j = max(children[j], key=lambda c: high[c])
        path.append(j)
    leg_chains = [_follow(children, c, lambda k: -low[k]) for c in legs]
    feet = [_limb(p, ch, _CHAIN["leg"]) for ch in leg_chains]
    toes = sum((p[f["Foot"]] - p[f["Ankle"]] for f in feet if "Foot" in f and "Ankle" in f), np.zeros(3))
    toes[1] = 0.0
    facing = toes / np.linalg.norm(toes) if np.linalg.norm(toes) > 1e-9 else np.array([0.0, 0.0, 1.0])
    right = np.cross(facing, UP)
    out = {"HipCenter": pelvis}
    _sided(out, p, leg_chains, feet, pelvis, right)
    if chest is None:
        return out
    if path[0] != chest:
        out["Spine"] = path[0]
    head_chain = _follow(children, neck, lambda c: high[c]) if neck is not None else []
    out["ShoulderCenter"] = head_chain[0] if len(head_chain) >= 2 else chest
    if head_chain:
        out["Head"] = head_chain[1] if len(head_chain) >= 2 else head_chain[0]
    arm_chains = [_follow(children, c, lambda k: reach(k, chest)) for c in arms]
    _sided(out, p, arm_chains, [_limb(p, ch, _CHAIN["arm"]) for ch in arm_chains], chest, right)
    return out


def _sided(out, p, chains, limbs, centre, right) -> None:
    """Name two limbs Left/Right by which side of `centre` their first joint lies on."""
    sides = [float((p[ch[0]] - p[centre]) @ right) for ch in chains]
    for side, limb in zip(("Right", "Left") if sides[0] > sides[1] else ("Left", "Right"), limbs):
        out.update({k + side: v for k, v in limb.items()})


def _follow(children, start, score) -> list[int]:
    chain, j = [start], start
    while children[j]:
        j = max(children[j], key=score)
        chain.append(j)
    return chain


def _limb(p, chain, parts) -> dict:
    """Upper and lower limb = the two longest consecutive bones of the chain; joints named from there."""
    if len(chain) < 3:
        return {}
    bones = np.linalg.norm(np.diff(p[chain], axis=0), axis=1)
    i = int(np.argmax(bones[:-1] + bones[1:]))
    return {part: chain[i + k] for k, part in enumerate(parts) if i + k < len(chain)}


def _subtree(children, j) -> list[int]:
    out, stack = [], [j]
    while stack:
        k = stack.pop()
        out.append(k)
        stack.extend(children[k])
    return out


def _depths(parents) -> list[int]:
    out = []
    for j in range(len(parents)):
        d, k = 0, parents[j]
        while k >= 0:
            d, k = d + 1, parents[k]
        out.append(d)
    return out


def _ancestors(parents, j) -> list[int]:
    out = []
    while j >= 0:
        out.append(j)
        j = parents[j]
    return out


def _is_ancestor(parents, a, j) -> bool:
    return a >= 0 and a in _ancestors(parents, j)


def _common_ancestor(parents, a, b) -> int:
    above = set(_ancestors(parents, a))
    return next((j for j in _ancestors(parents, b) if j in above), -1)


def _facing(p, found) -> np.ndarray:
    """Horizontal facing: from left -> right (hips, shoulders) when sides are known (forward = up x right),
    else from the feet (ankle -> toe), else +Z."""
    right = np.zeros(3)
    for a, b in (("HipLeft", "HipRight"), ("ShoulderLeft", "ShoulderRight")):
        if a in found and b in found:
            right += p[found[b]] - p[found[a]]
    right[1] = 0.0
    if np.linalg.norm(right) > 1e-9:
        f = np.cross(UP, right)
        return f / np.linalg.norm(f)
    toes = np.zeros(3)
    for s in ("Left", "Right"):
        if f"Ankle{s}" in found and f"Foot{s}" in found:
            toes += p[found[f"Foot{s}"]] - p[found[f"Ankle{s}"]]
    toes[1] = 0.0
    if np.linalg.norm(toes) > 1e-9:
        return toes / np.linalg.norm(toes)
    return np.array([0.0, 0.0, 1.0])


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
