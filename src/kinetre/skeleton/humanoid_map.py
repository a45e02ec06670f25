"""Which joint of any skeleton plays which Kinect-20 joint: the one mapper for BVH files, glTF/VRM animations,
recorded takes and rigged avatars.

A skeleton is given as joint names, parents and a rest pose (`map_humanoid`). The map is found in order:

1. a saved table (`fixed`, e.g. the avatar's JSON map) and the VRM humanoid bones, when given;
2. names: exact spellings (Kinect, Mixamo with or without `mixamorig:`, CMU, MocapBank), then the words of
   the name with side and noise removed, which covers Blender (`.L`/`.R`, `_l`/`_r`), Unreal (pelvis,
   spine_01, upperarm_l, lowerarm_l, hand_l, thigh_l, calf_l, foot_l, ball_l, neck_01), DAZ/Genesis
   (lThighBend, lShin, lShldrBend, lForearmBend, abdomenLower, chestUpper), Rokoko, VRoid (J_Bip_L_UpperArm),
   OpenNI and MediaPipe; numbered limb chains ("arm_joint_L_1..3") are assigned in order along the limb;
   twist, IK, pole and roll helpers never match;
3. topology: the pelvis is where the legs leave (their common ancestor), the shoulder centre is where the
   arm chains branch off the spine, the head continues the spine above it, a hand (foot) is the wrist's
   (ankle's) first child that is no finger;
4. bind-pose geometry, for what names and topology leave open: the pelvis is the shallowest joint with a
   chain reaching up and two reaching down; up that chain the chest is the first joint with two chains
   reaching away (held out or hanging); along a limb the two longest consecutive bones starting off the
   body's centre line are the upper and lower limb (a clavicle from the chest's middle is not); left and
   right come from the facing (the feet's ankle -> toe, else +Z). A skeleton that does not stand along +Y
   (a Z-up file) is tried along the other axes. Geometry fills a gap only in order along its chain and
   never with a helper joint.

Sides: where both feet have toes, the toes give the facing independently of any name; a limb pair whose
joint named left stands on the right of it (a mirrored skeleton: names that lie) is swapped, and the map
says so (`HumanoidMap.notes`). Without toes the names are kept.

Kinect-20 joints the skeleton lacks are derived where the paper's skeleton needs them: the Spine a quarter
of the way from the hip centre to the shoulder centre, a missing hip (shoulder) centre halfway between the
two hips (shoulders), a Hand (Foot) by extending the forearm (shin) by a quarter, or the whole arm (leg) by
an eighth without an elbow (knee). What neither maps nor can be derived is reported (`HumanoidMap.missing`,
`HumanoidMap.why`) and left untracked; a skeleton is refused as a humanoid only when it has neither a root
(hip centre) nor a limb chain (`HumanoidMap.drivable`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..rotation import up_rotation
from .models import KINECT20

UP = np.array([0.0, 1.0, 0.0])
TORSO = ("HipCenter", "Spine", "ShoulderCenter", "Head")
# The chains along a limb, from the body out.
LIMBS = {"arm": ("Shoulder", "Elbow", "Wrist", "Hand"), "leg": ("Hip", "Knee", "Ankle", "Foot")}
# Needed to drive a whole body; the others are used when present.
REQUIRED = ("HipCenter", "ShoulderCenter", "ShoulderLeft", "ElbowLeft", "WristLeft", "ShoulderRight",
            "ElbowRight", "WristRight", "HipLeft", "KneeLeft", "AnkleLeft", "HipRight", "KneeRight", "AnkleRight")

VRM_BONES = {"hips": "HipCenter", "spine": "Spine", "neck": "ShoulderCenter", "head": "Head",
             "leftUpperArm": "ShoulderLeft", "leftLowerArm": "ElbowLeft", "leftHand": "WristLeft",
             "leftMiddleProximal": "HandLeft", "rightUpperArm": "ShoulderRight", "rightLowerArm": "ElbowRight",
             "rightHand": "WristRight", "rightMiddleProximal": "HandRight", "leftUpperLeg": "HipLeft",
             "leftLowerLeg": "KneeLeft", "leftFoot": "AnkleLeft", "leftToes": "FootLeft",
             "rightUpperLeg": "HipRight", "rightLowerLeg": "KneeRight", "rightFoot": "AnkleRight",
             "rightToes": "FootRight"}

# Exact spellings (after `name_key`), best first: Kinect-20 itself, then Mixamo, CMU, MocapBank and generic
# names. "{s}" is "left"/"right", "{c}" is "l"/"r".
_EXACT = {
    "HipCenter": ["hipcenter", "hips", "hip", "pelvis", "spinebase", "root"],
    "Spine": ["spine", "spinemid", "chest", "spine1", "lowerback", "torso"],
    "ShoulderCenter": ["shouldercenter", "spineshoulder", "neck", "neck1", "neckbase"],
    "Head": ["head", "headtopend"],
    "Shoulder": ["shoulder{s}", "{s}arm", "{s}upperarm", "{c}shoulder", "{s}shoulder", "upperarm{c}", "{c}uparm"],
    "Elbow": ["elbow{s}", "{s}forearm", "{s}lowerarm", "{c}elbow", "{s}elbow", "lowerarm{c}", "{c}forearm"],
    "Wrist": ["wrist{s}", "{s}hand", "{c}wrist", "{s}wrist", "hand{c}", "{c}hand"],
    "Hand": ["hand{s}", "handtip{s}", "{s}handmiddle1", "{s}middleproximal", "middle01{c}", "{s}fingerbase",
             "{s}handindex1", "{s}handend", "{s}wristend", "{c}handend"],
    "Hip": ["hip{s}", "{s}upleg", "{s}thigh", "{s}upperleg", "{c}thigh", "{c}hip", "{s}hip", "upperleg{c}"],
    "Knee": ["knee{s}", "{s}leg", "{s}shin", "{s}lowerleg", "{c}knee", "{s}knee", "{c}shin", "lowerleg{c}"],
    "Ankle": ["ankle{s}", "{s}foot", "{c}ankle", "{s}ankle", "foot{c}", "{c}foot"],
    "Foot": ["foot{s}", "{s}toebase", "{s}toe", "{c}toe", "{s}toes", "{s}footend", "{s}ankleend", "toe{c}"],
}
# Words of a name (side, digits and noise removed, joined), best first per Kinect part.
_WORDS = {
    "HipCenter": ("hipcenter", "spinebase", "hips", "pelvis", "hip"),
    "Spine": ("spine", "spinemid", "lowerback", "abdomen", "abdomenlower", "abdomenupper", "chest", "chestlower"),
    "ShoulderCenter": ("shouldercenter", "spineshoulder", "neck", "necklower", "neckbase"),
    "Head": ("head", "nose"),
    "Shoulder": ("upperarm", "uparm", "arm", "shldrbend", "shldr", "shoulder"),
    "Elbow": ("forearm", "lowerarm", "forearmbend", "elbow"),
    "Wrist": ("wrist", "hand"),
    "Hand": ("handtip", "handend", "wristend", "hand", "index"),
    "Hip": ("upperleg", "upleg", "thigh", "thighbend", "hip"),
    "Knee": ("lowerleg", "shin", "calf", "knee", "leg"),
    "Ankle": ("ankle", "foot"),
    "Foot": ("toebase", "toe", "toes", "ball", "footindex", "footend", "ankleend", "foot"),
}
_NOISE = {"mixamorig", "j", "bip", "b", "def", "org", "mch", "joint", "jnt", "bone", "c", "cc", "base", "bn", "sk"}
_HELPERS = {"twist", "ik", "pole", "target", "roll", "ctrl", "helper", "collar", "clavicle", "eye", "jaw",
            "thumb", "pinky", "ring", "middle", "heel", "tail", "ear", "mouth", "socket", "attach", "prop",
            "weapon", "slot", "mount", "attachment"}
_SIDES = {"left": "Left", "l": "Left", "right": "Right", "r": "Right"}


@dataclass(frozen=True, eq=False)
class HumanoidMap:
    """Kinect-20 joint -> source joint, how each was found, what is derived and what is missing.

    Attributes
    ----------
    names : tuple of str, (J,)
        The source skeleton's joint names.
    joints : dict str -> int
        Kinect joint -> source joint index, for joints the skeleton has.
    how : dict str -> str
        "file", "vrm", "name", "topology" or "geometry" per mapped joint.
    derived : dict str -> tuple of (int, float)
        Kinect joint -> (source joint, weight) pairs blending its position from the source's joints.
    facing : (3,) float64
        Horizontal unit vector the skeleton faces in its rest pose.
    notes : tuple of str
        What the map decided against the names (sides swapped by geometry), for `describe`.
    parents : tuple of int, (J,)
        The source skeleton's parent per joint (-1: a root).
    """

    names: tuple[str, ...]
    joints: dict
    how: dict
    derived: dict
    facing: np.ndarray
    notes: tuple[str, ...] = ()
    parents: tuple[int, ...] = ()

    @property
    def missing(self) -> tuple[str, ...]:
        """Kinect joints of `REQUIRED` the skeleton does not have (derived ones do not count)."""
        return tuple(j for j in REQUIRED if j not in self.joints)

    @property
    def unmapped(self) -> tuple[str, ...]:
        """Kinect joints neither mapped nor derived: left untracked."""
        return tuple(j for j in KINECT20.joints if j not in self.joints and j not in self.derived)

    @property
    def unused(self) -> tuple[str, ...]:
        """Source joints no Kinect joint reads."""
        used = set(self.joints.values()) | {j for pairs in self.derived.values() for j, _ in pairs}
        return tuple(n for j, n in enumerate(self.names) if j not in used)

    @property
    def limbs(self) -> tuple[str, ...]:
        """The limbs ("arm left", "leg right", ...) with a chain: one joint mapped and another mapped or
        derived (a one-bone arm: the shoulder, and the wrist its part's end gives)."""
        out = []
        for limb, parts in LIMBS.items():
            for side in ("Left", "Right"):
                mapped = sum(p + side in self.joints for p in parts)
                if mapped and mapped + sum(p + side in self.derived for p in parts) >= 2:
                    out.append(f"{limb} {side.lower()}")
        return tuple(out)

    @property
    def drivable(self) -> bool:
        """A root or a limb chain maps: enough to drive what maps."""
        return "HipCenter" in self.joints or bool(self.limbs)

    def weights(self) -> np.ndarray:
        """(20, J) Kinect positions = weights @ source positions; rows of `unmapped` joints are zero."""
        w = np.zeros((len(KINECT20.joints), len(self.names)))
        for kj, j in self.joints.items():
            w[KINECT20.index(kj), j] = 1.0
        for kj, pairs in self.derived.items():
            for j, a in pairs:
                w[KINECT20.index(kj), j] += a
        return w

    def drivers(self) -> dict:
        """Kinect joint -> the source joint(s) it comes from, as text (for `kinetre info`)."""
        out = {}
        for kj in KINECT20.joints:
            if kj in self.joints:
                out[kj] = self.names[self.joints[kj]]
            elif kj in self.derived:
                out[kj] = " + ".join(f"{a:g} {self.names[j]}" for j, a in self.derived[kj]).replace("+ -", "- ")
        return out

    def why(self, kj: str) -> str:
        """Why Kinect joint `kj` is untracked (for one of `unmapped`)."""
        part, side = _kinect_part(kj)
        if not side:
            return "no joint of the spine plays it"
        chain = _chain_of(kj)
        have = [k for k in chain if k in self.joints]
        if not have:
            return f"no {side.lower()} {next(limb for limb, parts in LIMBS.items() if part in parts)} maps"
        i = chain.index(kj)
        before = [k for k in chain[:i] if k in self.joints]
        after = [k for k in chain[i + 1:] if k in self.joints]
        if before and after:
            return f"no joint between {self.names[self.joints[before[-1]]]} and {self.names[self.joints[after[0]]]}"
        if before:
            return f"nothing beyond {self.names[self.joints[before[-1]]]} and no bone before it to extend"
        return f"no joint before {self.names[self.joints[after[0]]]}"

    def describe(self) -> list[str]:
        """Lines: each Kinect joint <- source joint (how), then what is derived, what does not map and why."""
        lines = [f"{kj} <- {self.names[self.joints[kj]]} ({self.how[kj]})" for kj in KINECT20.joints
                 if kj in self.joints]
        d = self.drivers()
        lines += [f"{kj} <- {d[kj]} (derived)" for kj in KINECT20.joints if kj in self.derived]
        if self.unmapped:
            lines.append(f"not mapped (untracked): {', '.join(self.unmapped)}")
            lines += [f"  {kj}: {self.why(kj)}" for kj in self.unmapped]
        return lines + list(self.notes)


def name_key(name: str) -> str:
    """Comparable joint name: no namespace ("mixamorig:"), lower case, letters and digits only.

    >>> name_key("mixamorig:LeftArm")
    'leftarm'
    """
    return re.sub(r"[^a-z0-9]", "", name.rsplit(":", 1)[-1].lower())


def name_words(name: str) -> tuple[str, str, tuple[int, ...]]:
    """(side "Left"/"Right"/"", the words joined without side and noise, the numbers) of a joint name;
    a helper joint (twist, IK, pole, finger...) gives the word "".

    >>> name_words("upperarm_twist_01_l")
    ('Left', '', (1,))
    >>> name_words("lShldrBend"), name_words("thigh.R"), name_words("J_Bip_L_UpperArm")
    (('Left', 'shldrbend', ()), ('Right', 'thigh', ()), ('Left', 'upperarm', ()))
    """
    toks = name_tokens(name)
    sides = {_SIDES[t] for t in toks if t in _SIDES}
    side = sides.pop() if len(sides) == 1 else ""
    digits = tuple(int(t) for t in toks if t.isdigit())
    if _HELPERS & set(toks):
        return side, "", digits
    return side, "".join(t for t in toks if not t.isdigit() and t not in _NOISE and t not in _SIDES), digits


def name_tokens(name: str) -> list[str]:
    """The lower-case words and numbers of a joint name (camel case, separators and namespace split).

    >>> name_tokens("mixamorig:LeftUpLeg"), name_tokens("socket_hand_L")
    (['left', 'up', 'leg'], ['socket', 'hand', 'l'])
    """
    return [t.lower() for t in re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+", name.rsplit(":", 1)[-1])]


def is_helper(name: str) -> bool:
    """A twist, IK, pole, finger... joint by its name: it never plays a Kinect joint.

    >>> is_helper("LeftHandThumb1"), is_helper("joint3")
    (True, False)
    """
    return bool(_HELPERS & set(name_tokens(name)))


def map_humanoid(names, parents, rest: np.ndarray, vrm: dict | None = None,
                 fixed: dict | None = None, tips: int = 0) -> HumanoidMap:
    """Map a skeleton to Kinect-20 (the order of the module docstring).

    Parameters
    ----------
    names : sequence of str, (J,)
    parents : sequence of int, (J,)
        Parent joint per joint, -1 for a root.
    rest : (J, 3) float
        Joint positions in the rest (bind) pose, +Y up.
    vrm : dict, optional
        VRM humanoid bone name -> joint index.
    fixed : dict, optional
        Kinect joint -> joint index that wins over everything (a saved map).
    tips : int
        How many of the last joints are part ends (`kinetre.skeleton.tips`: where a childless joint's
        skinned part ends), not joints: they play no Kinect joint, but a limb of one bone (a shoulder whose
        part is the whole arm) reaches its elbow and wrist through them.
    """
    names = tuple(names)
    parents = [int(p) for p in parents]
    p = np.asarray(rest, dtype=np.float64).reshape(len(names), 3)
    n = len(names) - int(tips)
    if n < 0 or any(q >= n for q in parents[:n]):
        raise ValueError("map_humanoid: tips must be childless joints after the skeleton's own")
    found, how, notes = _map_joints(names[:n], parents[:n], p[:n], vrm, fixed)
    ends = {parents[t]: t for t in range(n, len(names)) if parents[t] >= 0}
    _one_bone_arms(found, how, parents, p, ends)
    derived = _derive(found, parents, names, ends)
    return HumanoidMap(names, found, how, derived, _facing(p, found), tuple(notes), tuple(parents))


def _map_joints(names, parents, p, vrm, fixed) -> tuple[dict, dict, list]:
    found: dict[str, int] = {}
    how: dict[str, str] = {}

    def put(kj, j, kind):
        if kind == "geometry" and (is_helper(names[j]) or not _in_chain(found, kj, j, parents)):
            return
        if kj not in found and j not in found.values():
            found[kj], how[kj] = int(j), kind

    for kj, j in (fixed or {}).items():
        found[kj], how[kj] = int(j), "file"
    for bone, kj in VRM_BONES.items():
        if vrm and bone in vrm:
            put(kj, vrm[bone], "vrm")
    if not vrm:
        for kj, j in _by_name(names, parents).items():
            put(kj, j, "name")
        _limb_starts(found, how, names, parents)
    _by_topology(found, how, names, parents, p)
    notes = _sides_by_feet(found, how, parents, p)
    if any(j not in found for j in REQUIRED) or "Spine" not in found or "Head" not in found:
        for kj, j in _by_geometry(p, parents).items():
            put(kj, j, "geometry")
    return found, how, notes


def _limb_starts(found, how, names, parents) -> None:
    """A limb of one bone names its bone by the limb ("leg-left", "LeftLeg" straight off the hips): the
    bone leaving the body is the limb's first joint (hip, shoulder), whatever the name says."""
    for parts in LIMBS.values():
        for side in ("Left", "Right"):
            first, second = parts[0] + side, parts[1] + side
            if first in found or second not in found or how[second] != "name":
                continue
            up = parents[found[second]]
            if up < 0 or name_words(names[up])[0] == "":   # hangs off the body (no side), not off a limb
                found[first], how[first] = found.pop(second), how.pop(second)


def _one_bone_arms(found, how, parents, p, ends) -> None:
    """A hand hanging straight off the chest whose part reaches far from its joint (the joint sits at the
    shoulder, the hand at the part's far end) is the whole arm: it plays the shoulder."""
    for side in ("Left", "Right"):
        w = found.get("Wrist" + side)
        if w is None or "Shoulder" + side in found or "Elbow" + side in found or w not in ends or parents[w] < 0:
            continue
        if how["Wrist" + side] in ("file", "vrm"):
            continue
        if np.linalg.norm(p[ends[w]] - p[w]) > 0.5 * np.linalg.norm(p[w] - p[parents[w]]):
            found["Shoulder" + side], how["Shoulder" + side] = found.pop("Wrist" + side), "topology"
            how.pop("Wrist" + side)
            if found.get("Hand" + side) is not None and how.get("Hand" + side) == "topology":
                del found["Hand" + side], how["Hand" + side]


def take_map(names, parents, rest: np.ndarray | None, fixed: dict | None = None, tips: int = 0,
             vrm: dict | None = None) -> HumanoidMap | None:
    """The map a motion source is turned into Kinect-20 by, or None when its skeleton is not a humanoid
    (no hip centre, mapped or derived; no limb chain; more than two legs; or legs that do not continue its
    spine: an animal then drives a mesh by its own bones). Without `rest`, names and topology alone decide."""
    hmap = map_humanoid(names, parents, np.zeros((len(names), 3)) if rest is None else rest, vrm=vrm, fixed=fixed,
                        tips=tips)
    return None if not_humanoid(hmap, rest) else hmap


def not_humanoid(hmap: HumanoidMap, rest: np.ndarray | None) -> str:
    """Why a motion source's map does not make it a humanoid ("" when it does), for `take_map`."""
    if not hmap.limbs:
        return "no limb chain maps"
    if "HipCenter" not in hmap.joints and "HipCenter" not in hmap.derived:
        return "no hip centre maps"
    if rest is None:
        return ""
    legs = leg_count(hmap, rest)
    if legs > 2:
        return f"{legs} legs reach the floor"
    return "; ".join(upright_problems(hmap, rest, up=None))


def leg_count(hmap: HumanoidMap, rest: np.ndarray) -> int:
    """How many chains leave the body and reach the floor in the rest pose: the branches, at the deepest
    joint every floor joint below the hip centre hangs from, that hold floor joints (a humanoid's two legs;
    a spider's eight).

    The floor is the lowest joint along the torso's down (hips -> shoulder centre or head), along -Y
    without one; a floor joint lies within 5 % of the skeleton's extent of it. Tips (part ends) count as
    joints."""
    p = np.asarray(rest, dtype=np.float64)
    m = hmap.joints
    top = next((m[k] for k in ("ShoulderCenter", "Head") if k in m), None)
    up = UP
    if "HipCenter" in m and top is not None and np.linalg.norm(p[top] - p[m["HipCenter"]]) > 1e-12:
        up = (p[top] - p[m["HipCenter"]]) / np.linalg.norm(p[top] - p[m["HipCenter"]])
    return _floor_chains(list(hmap.parents), p, up, m.get("HipCenter", -1))


def _floor_chains(parents, p, up, body) -> int:
    height = p @ up
    extent = float(np.ptp(p, axis=0).max())
    floor = [j for j in range(len(p)) if height[j] < height.min() + 0.05 * extent]
    if body >= 0:                                    # legs leave the body (an IK foot on the armature does not)
        below = [j for j in floor if _is_ancestor(parents, body, j)]
        floor = below if below else floor
    if len(floor) < 2:
        return len(floor)
    branch = floor[0]
    for j in floor[1:]:
        branch = _common_ancestor(parents, branch, j)
        if branch < 0:
            return len(floor)
    groups = set()
    for j in floor:
        if j == branch:
            continue
        chain = _ancestors(parents, j)
        groups.add(chain[chain.index(branch) - 1])
    return len(groups)


def kinect_frames(hmap: HumanoidMap, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Source joint positions (..., J, 3) -> Kinect-20 (..., 20, 3) and tracked (..., 20).

    A Kinect joint that does not map sits on its nearest mapped ancestor (finite, so bounds and fits stay
    sound) and is untracked.
    """
    positions = np.asarray(positions, dtype=np.float64)
    out = np.einsum("kj,...jc->...kc", hmap.weights(), positions)
    tracked = np.ones(out.shape[:-1], dtype=bool)
    have = set(hmap.joints) | set(hmap.derived)
    for k, kj in enumerate(KINECT20.joints):
        if kj in have:
            continue
        tracked[..., k] = False
        a = KINECT20.parents[k]
        while a >= 0 and KINECT20.joints[a] not in have:
            a = KINECT20.parents[a]
        if a >= 0:
            out[..., k, :] = out[..., a, :]
        else:                                        # nothing above maps: the first mapped joint stands in
            first = next(i for i, name in enumerate(KINECT20.joints) if name in have)
            out[..., k, :] = out[..., first, :]
    return out, tracked


def upright_problems(hmap: HumanoidMap, rest: np.ndarray, up: np.ndarray | None = UP) -> list[str]:
    """Why the rest pose is not an upright biped (empty when it is).

    With `up` (an avatar, whose file says +Y is up): the torso (hips -> shoulder centre, else head) within
    45 degrees of `up` and both legs (hip -> ankle, else knee) within 60 degrees of down. With `up=None` (a
    motion file whose up axis is not trusted): the legs run opposite to the torso within 60 degrees, which
    a quadruped's (legs at right angles to a level spine) do not.
    """
    p, m = np.asarray(rest, dtype=np.float64), hmap.joints
    top = next((k for k in ("ShoulderCenter", "Head") if k in m), None)
    if "HipCenter" not in m or top is None:
        return []

    def direction(a, b):
        v = p[m[b]] - p[m[a]]
        n = np.linalg.norm(v)
        return None if n < 1e-12 else v / n

    def angle(u, v):
        return float(np.degrees(np.arccos(np.clip(u @ v, -1.0, 1.0))))

    torso = direction("HipCenter", top)
    legs = []
    for s in ("Left", "Right"):
        end = next((k + s for k in ("Ankle", "Knee") if k + s in m), None)
        if f"Hip{s}" in m and end is not None and (d := direction(f"Hip{s}", end)) is not None:
            legs.append(d)
    problems = []
    name = lambda k: hmap.names[m[k]]  # noqa: E731
    if torso is None:
        return [f"its spine ({name('HipCenter')} -> {name(top)}) has no length"]
    if up is not None:
        if angle(torso, up) > 45:
            problems.append(f"its spine ({name('HipCenter')} -> {name(top)}) is {angle(torso, up):.0f} degrees "
                            f"from vertical")
        if legs and max(angle(leg, -up) for leg in legs) > 60:
            problems.append(f"its legs point {max(angle(leg, -up) for leg in legs):.0f} degrees away from down")
    elif legs and max(angle(leg, -torso) for leg in legs) > 60:
        problems.append(f"its legs are {max(angle(leg, -torso) for leg in legs):.0f} degrees off the line of its "
                        f"spine")
    return problems


def parse_table(table: dict, names, where: str, error=ValueError) -> dict:
    """Kinect joint -> joint index from a saved table of joint names, "#index" strings or ints.

    Raises `error` naming `where` on an unknown Kinect joint, a name that is not one joint's, or an index
    out of range.
    """
    names = list(names)
    out = {}
    for kj, ref in table.items():
        if kj not in KINECT20.joints:
            raise error(f"{where}: {kj!r} is not a Kinect-20 joint ({', '.join(KINECT20.joints)})")
        if ref is None or ref == "":
            continue
        if isinstance(ref, int) or (isinstance(ref, str) and ref.startswith("#") and ref[1:].isdigit()):
            j = int(ref if isinstance(ref, int) else ref[1:])
            if not 0 <= j < len(names):
                raise error(f"{where}: {kj}: joint #{j} is outside the skeleton's {len(names)} joints")
        elif isinstance(ref, str) and names.count(ref) == 1:
            j = names.index(ref)
        else:
            raise error(f"{where}: {kj}: the skeleton has no single joint named {ref!r}")
        out[kj] = j
    return out


def table_of(joints: dict, names) -> dict:
    """The saveable form of a map: Kinect joint -> joint name where unique, else "#index"."""
    names = list(names)
    return {kj: names[j] if names.count(names[j]) == 1 else f"#{j}"
            for kj, j in sorted(joints.items(), key=lambda kv: KINECT20.index(kv[0]))}


# ---- by name ------------------------------------------------------------------------------------------

def _kinect_part(kj: str) -> tuple[str, str]:
    for side in ("Left", "Right"):
        if kj.endswith(side):
            return kj[:-len(side)], side
    return kj, ""


def _by_name(names, parents) -> dict:
    depth = _depths(parents)
    keys = [name_key(n) for n in names]
    found: dict[str, int] = {}
    for kj in KINECT20.joints:                       # exact spellings first
        part, side = _kinect_part(kj)
        s = side.lower()
        for c in _EXACT[part]:
            c = c.format(s=s, c=s[:1])
            hits = [j for j, k in enumerate(keys) if k == c and j not in found.values()]
            if hits:
                found[kj] = min(hits, key=lambda j: depth[j])
                break
    words = [name_words(n) for n in names]
    chains: dict[tuple[str, str], list[tuple[tuple, int]]] = {}
    for j, (side, word, digits) in enumerate(words):
        if side and word in LIMBS and digits:        # "arm_joint_L_1", "b_LeftLeg01_015": in order along it
            chains.setdefault((side, word), []).append((digits, j))
    for (side, limb), members in chains.items():
        for part, (_, j) in zip(LIMBS[limb], sorted(members)):
            if part + side not in found and j not in found.values():
                found[part + side] = j
    chained = {j for members in chains.values() for _, j in members}
    # torso and inner limb joints before the ends, so "hand" is the wrist unless a "wrist" exists
    order = [kj for kj in KINECT20.joints if not kj.startswith(("Hand", "Foot"))] + \
            [kj for kj in KINECT20.joints if kj.startswith(("Hand", "Foot"))]
    for kj in order:
        if kj in found:
            continue
        part, side = _kinect_part(kj)
        best = None
        for j, (s, word, digits) in enumerate(words):
            if j in found.values() or j in chained or s != side or word not in _WORDS[part]:
                continue
            if part in ("Hand", "Foot"):             # an end hangs below its wrist (ankle), when known
                inner = ("Wrist" if part == "Hand" else "Ankle") + side
                if inner in found and not _is_ancestor(parents, found[inner], j):
                    continue
            score = (_WORDS[part].index(word), digits[:1] or (0,), depth[j])
            if best is None or score < best[0]:
                best = (score, j)
        if best is not None:
            found[kj] = best[1]
    return found


# ---- by topology --------------------------------------------------------------------------------------

def _by_topology(found, how, names, parents, p) -> None:
    """Pelvis = the legs' common ancestor, shoulder centre = the arms' branch point, head above it,
    hands and feet = the wrist's and ankle's children (only where no saved map decided)."""
    children = _children(parents)

    def claim(kj, j):
        other = next((k for k, v in found.items() if v == j and k != kj), None)
        if other is not None:
            if how[other] == "file":
                return
            del found[other], how[other]             # the joint plays the part topology gives it
        found[kj], how[kj] = j, "topology"

    if "HipLeft" in found and "HipRight" in found and how.get("HipCenter") != "file":
        lca = _common_ancestor(parents, found["HipLeft"], found["HipRight"])
        hc = found.get("HipCenter", -1)
        # a hip centre named above the legs' branch stays (a pelvis helper below it), unless it lies far
        # from the branch (a root on the floor under a game rig's body)
        leg = max(np.linalg.norm(p[_subtree(children, found[k])] - p[lca], axis=1).max()
                  for k in ("HipLeft", "HipRight")) if lca >= 0 else 0.0
        far = hc >= 0 and lca >= 0 and np.linalg.norm(p[hc] - p[lca]) > 0.5 * leg
        if lca >= 0 and hc != lca and (far or not _is_ancestor(parents, hc, found["HipLeft"])):
            found.pop("HipCenter", None)
            claim("HipCenter", lca)
    # where the arms branch off: from their first joints (a hand straight off the chest is one)
    starts = [next((found[k + s] for k in LIMBS["arm"][:3] if k + s in found), None) for s in ("Left", "Right")]
    if None not in starts and "ShoulderCenter" not in found:
        lca = _common_ancestor(parents, *starts)
        if lca >= 0 and lca != found.get("HipCenter") and lca not in starts:
            claim("ShoulderCenter", lca)
    if "ShoulderCenter" in found and "Head" not in found:
        arms = {a for a in starts if a is not None}
        up = [c for c in children[found["ShoulderCenter"]]
              if not any(_is_ancestor(parents, c, a) for a in arms) and c not in found.values()]
        if up:
            j = max(up, key=lambda c: p[c, 1])
            if children[j]:                          # a neck the name did not say: the head is above it
                j = max(children[j], key=lambda c: p[c, 1])
            found["Head"], how["Head"] = j, "topology"
    for side in ("Left", "Right"):
        for end, inner in ((f"Hand{side}", f"Wrist{side}"), (f"Foot{side}", f"Ankle{side}")):
            if end not in found and inner in found:
                kids = [c for c in children[found[inner]] if c not in found.values() and not is_helper(names[c])]
                if kids:                             # the first child, e.g. an End Site (a thumb is no hand)
                    found[end], how[end] = kids[0], "topology"


def _chain_of(kj: str) -> tuple[str, ...]:
    part, side = _kinect_part(kj)
    if not side:
        return TORSO
    return tuple(k + side for k in next(parts for parts in LIMBS.values() if part in parts))


def _in_chain(found, kj, j, parents) -> bool:
    """Geometry fills a gap only in order: below the joints the chain has before it, above those after it
    (so a skeleton without elbows gets no elbow from its hand or fingers)."""
    chain = _chain_of(kj)
    i = chain.index(kj)
    return all(_is_ancestor(parents, found[k], j) and found[k] != j for k in chain[:i] if k in found) and \
        all(_is_ancestor(parents, j, found[k]) and found[k] != j for k in chain[i + 1:] if k in found)


def _sides_by_feet(found, how, parents, p) -> list[str]:
    """Names that lie about sides lose to geometry: where both feet have toes (a Foot below its Ankle), the
    toes give the facing without the sides; a limb pair whose joint called left lies clearly on the right of
    that facing (a mirrored skeleton) is swapped. Without toes the names are kept. Returns notes."""
    toes, feet = np.zeros(3), 0
    for s in ("Left", "Right"):
        a, f = found.get(f"Ankle{s}"), found.get(f"Foot{s}")
        if a is not None and f is not None and _is_ancestor(parents, a, f):
            toes, feet = toes + p[f] - p[a], feet + 1
    top = found.get("ShoulderCenter", found.get("Head"))
    if feet < 2 or "HipCenter" not in found or top is None:
        return []
    up = p[top] - p[found["HipCenter"]]
    if np.linalg.norm(up) < 1e-9:
        return []
    up /= np.linalg.norm(up)
    toes -= (toes @ up) * up
    if np.linalg.norm(toes) < 1e-9:
        return []
    right = np.cross(toes / np.linalg.norm(toes), up)
    notes = []
    for limb, parts in LIMBS.items():
        pair = next((k for k in parts if k + "Left" in found and k + "Right" in found), None)
        if pair is None:
            continue
        d = p[found[pair + "Right"]] - p[found[pair + "Left"]]
        keys = [k + s for k in parts for s in ("Left", "Right") if k + s in found]
        if d @ right >= -0.25 * np.linalg.norm(d) or any(how[k] in ("file", "vrm") for k in keys):
            continue
        swapped = {(k[:-4] + "Right" if k.endswith("Left") else k[:-5] + "Left"): found[k] for k in keys}
        for k in keys:
            del found[k], how[k]
        for k, j in swapped.items():
            found[k], how[k] = j, "geometry"
        notes.append(f"the {limb}s named left lie on the right of the facing the feet give (a mirrored "
                     f"skeleton): sides swapped by geometry")
    return notes


def _derive(found, parents, names, ends=None) -> dict:
    """Blends for the paper's joints the skeleton lacks (module docstring); `ends`: childless joint -> the
    tip where its part ends, by which a limb that stops at its shoulder or elbow (hip or knee) reaches on:
    the end is its wrist (ankle), halfway there its elbow (knee)."""
    out: dict[str, tuple] = {}
    ends = ends or {}

    def source(kj):
        if kj in found:
            return ((found[kj], 1.0),)
        return out.get(kj)

    def blend(*terms):
        acc: dict[int, float] = {}
        for a, pairs in terms:
            for j, w in pairs:
                acc[j] = acc.get(j, 0.0) + a * w
        return tuple((j, w) for j, w in acc.items() if abs(w) > 1e-12)

    for side in ("Left", "Right"):
        for parts in LIMBS.values():
            chain = [k + side for k in parts[:3]]
            have = [k for k in chain if k in found]
            if not have or chain[2] in found or found[have[-1]] not in ends:
                continue
            last, tip = found[have[-1]], ends[found[have[-1]]]
            if have[-1] == chain[0] and chain[1] not in found:
                out[chain[1]] = ((tip, 0.5), (last, 0.5))
            out[chain[2]] = ((tip, 1.0),)
    for centre, a, b in (("HipCenter", "HipLeft", "HipRight"), ("ShoulderCenter", "ShoulderLeft", "ShoulderRight")):
        if centre not in found and source(a) and source(b):
            out[centre] = blend((0.5, source(a)), (0.5, source(b)))
    if "Spine" not in found and source("HipCenter") and source("ShoulderCenter"):
        out["Spine"] = blend((0.75, source("HipCenter")), (0.25, source("ShoulderCenter")))
    for side in ("Left", "Right"):
        for end, mid, base, root in ((f"Hand{side}", f"Wrist{side}", f"Elbow{side}", f"Shoulder{side}"),
                                     (f"Foot{side}", f"Ankle{side}", f"Knee{side}", f"Hip{side}")):
            if end in found or not source(mid):
                continue
            if source(base):
                out[end] = blend((1.25, source(mid)), (-0.25, source(base)))
            elif source(root):                       # no elbow (knee): a quarter of half the limb
                out[end] = blend((1.125, source(mid)), (-0.125, source(root)))
    return out


# ---- by geometry --------------------------------------------------------------------------------------

# The signed axes a skeleton may stand along: +Y (glTF, BVH) first, then Z-up and the others.
_AXES = [np.array(a, dtype=np.float64) for a in ((0, 1, 0), (0, 0, 1), (0, 0, -1), (1, 0, 0), (-1, 0, 0),
                                                  (0, -1, 0))]


def _by_geometry(p, parents) -> dict:
    """The structural map of the module docstring, standing the skeleton along +Y, else along the axis that
    finds the most joints (a Z-up file); {} when no pelvis is found."""
    best: dict = {}
    for axis in _AXES:
        found = _by_geometry_up(p @ up_rotation(axis).T, parents)
        if "ShoulderCenter" in found and len(found) >= 2 + 2 * len(LIMBS["leg"]):
            return found
        if len(found) > len(best):
            best = found
    return best


def _by_geometry_up(p, parents) -> dict:
    n = len(p)
    if n < 3:
        return {}
    children = _children(parents)
    subtree = [_subtree(children, j) for j in range(n)]
    height = max(float(np.ptp(p[:, 1])), 1e-9)
    low = np.array([p[s, 1].min() for s in subtree])
    high = np.array([p[s, 1].max() for s in subtree])
    depth = _depths(parents)
    pelvis = legs = up = None
    for j in sorted(range(n), key=lambda j: depth[j]):
        # the chain reaching highest is the spine; of the others, those reaching down are legs (arms that hang
        # below the hips belong to the spine's chain)
        ups = [c for c in children[j] if high[c] > p[j, 1] + 0.12 * height]
        if not ups:
            continue
        top = max(ups, key=lambda c: high[c])
        down = [c for c in children[j] if c != top and low[c] < p[j, 1] - 0.12 * height]
        if len(down) >= 2:
            pelvis, legs, up = j, sorted(down, key=lambda c: low[c])[:2], top
            break
    if pelvis is None:
        return {}

    def reach(j, origin):
        d = p[subtree[j]] - p[origin]
        return float(np.hypot(d[:, 0], d[:, 2]).max())

    def extent(j, origin):                           # arms held out or hanging down alike
        return float(np.linalg.norm(p[subtree[j]] - p[origin], axis=1).max())

    chest, arms, neck, j = None, [], None, up
    path = [up]
    while True:
        onward = max(children[j], key=lambda c: high[c]) if children[j] else None
        side, far = [c for c in children[j] if c != onward and extent(c, j) > 0.15 * height], extent
        if len(side) < 2:                            # the arms may branch off the highest chain too
            side, far = [c for c in children[j] if reach(c, j) > 0.15 * height], reach
        if len(side) >= 2:
            chest, arms = j, sorted(side, key=lambda c: -far(c, j))[:2]
            rest = [c for c in children[j] if c not in arms]
            neck = max(rest, key=lambda c: high[c]) if rest else None
            break
        if not children[j]:
            break
        j = max(children[j], key=lambda c: high[c])
        path.append(j)
    leg_chains = [_follow(children, c, lambda k: -low[k]) for c in legs]
    feet = [_limb(p, ch, LIMBS["leg"], pelvis, height) for ch in leg_chains]
    toes = sum((p[f["Foot"]] - p[f["Ankle"]] for f in feet if "Foot" in f and "Ankle" in f), np.zeros(3))
    toes[1] = 0.0
    facing = toes / np.linalg.norm(toes) if np.linalg.norm(toes) > 1e-9 else np.array([0.0, 0.0, 1.0])
    right = np.cross(facing, UP)
    out = {"HipCenter": pelvis}
    _sided(out, p, leg_chains, feet, pelvis, right)
    if chest is None:                                # no arms: the spine's chain alone, the head on top
        line = [k for k in path if p[k, 1] > p[pelvis, 1] + 0.02 * height]
        if line:
            out["Head"] = line[-1]
        if len(line) >= 2:
            out["Spine"] = line[0]
        if len(line) >= 3:
            out["ShoulderCenter"] = line[-2]
        return out
    # the spine: the lowest joint between the pelvis and the chest that stands above the pelvis
    spine = [k for k in path if k != chest and p[k, 1] > p[pelvis, 1] + 0.02 * height]
    if spine:
        out["Spine"] = spine[0]
    arm_chains = [_follow(children, c, lambda k: far(k, chest)) for c in arms]
    arm_limbs = [_limb(p, ch, LIMBS["arm"], chest, height) for ch in arm_chains]
    _sided(out, p, arm_chains, arm_limbs, chest, right)
    # up the chain above the chest: a first joint at most a little above the shoulders is the neck's base
    # (the shoulder centre), else the chest is; the head is the joint nearest the middle between the
    # shoulders and the chain's top (the skull's base and its top end lie either side)
    head_chain = _follow(children, neck, lambda c: high[c]) if neck is not None else []
    shoulders = float(np.mean([p[limb["Shoulder"], 1] for limb in arm_limbs if "Shoulder" in limb] or [p[chest, 1]]))
    out["ShoulderCenter"] = chest
    if len(head_chain) >= 2 and p[head_chain[0], 1] < shoulders + 0.08 * height:
        out["ShoulderCenter"] = head_chain.pop(0)
    if head_chain:
        middle = 0.5 * (shoulders + p[head_chain, 1].max())
        out["Head"] = min(head_chain, key=lambda k: abs(p[k, 1] - middle))
    return out


def _sided(out, p, chains, limbs, centre, right) -> None:
    """Name two limbs Left/Right by which side of `centre` they lie on (the mean of their joints: a clavicle
    may start on the centre line)."""
    sides = [float((p[ch].mean(axis=0) - p[centre]) @ right) for ch in chains]
    for side, limb in zip(("Right", "Left") if sides[0] > sides[1] else ("Left", "Right"), limbs):
        out.update({k + side: v for k, v in limb.items()})


def _follow(children, start, score) -> list[int]:
    chain, j = [start], start
    while children[j]:
        j = max(children[j], key=score)
        chain.append(j)
    return chain


def _limb(p, chain, parts, centre, height) -> dict:
    """Upper and lower limb = the two longest consecutive bones of the chain that start off the body's
    centre line (a clavicle from the middle of the chest, a hip joint at the pelvis, is neither); joints
    named from there. A chain of two joints gives the first two parts."""
    if len(chain) < 2:
        return {}
    if len(chain) == 2:
        return dict(zip(parts, chain))
    bones = np.linalg.norm(np.diff(p[chain], axis=0), axis=1)
    off = np.hypot(*(p[chain] - p[centre])[:, [0, 2]].T) > 0.03 * height
    pair = bones[:-1] + bones[1:]
    pair = np.where(off[:-2], pair, pair - pair.max() - 1.0)      # a pair from the centre line only if all are
    i = int(np.argmax(pair))
    return {part: chain[i + k] for k, part in enumerate(parts) if i + k < len(chain)}


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


# ---- tree helpers -------------------------------------------------------------------------------------

def _children(parents) -> list[list[int]]:
    out = [[] for _ in parents]
    for c, q in enumerate(parents):
        if q >= 0:
            out[q].append(c)
    return out


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
