"""The skeleton mapper on every public BVH and avatar, and on variants made from their skeletons: renamed to
each rig convention, given meaningless names, with the neck, spine or elbows removed, and mirrored."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from kinetre.avatar.load import load_avatar
from kinetre.motion.bvh import parse_bvh, rest_positions
from kinetre.skeleton.humanoid_map import REQUIRED, UP, map_humanoid, take_map
from kinetre.skeleton.models import KINECT20

LIMB_JOINTS = [p + s for s in ("Left", "Right") for p in ("Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle")]


@dataclass(frozen=True)
class Skel:
    names: tuple
    parents: tuple
    rest: np.ndarray

    def map(self):
        return map_humanoid(self.names, self.parents, self.rest)

    def index(self, name):
        return self.names.index(name)


def load(data_dir, name) -> Skel:
    if name.endswith(".bvh"):
        clip = parse_bvh((data_dir / "bvh" / name).read_text(), source=name)
        return Skel(tuple(clip.names), tuple(clip.parents), rest_positions(clip))
    a = load_avatar(data_dir / "avatars" / name)
    return Skel(tuple(a.joint_names), tuple(int(p) for p in a.joint_parents), np.asarray(a.bind_positions))


# The expected map of each public file (Kinect joint -> its joint name); Hand/Foot may also be derived.
BVH_TRUTH = {
    "cmu_01_01_hops.bvh": "cmu", "cmu_12_01_walk.bvh": "cmu", "mixamo_rig_freebvh.bvh": "mixamo",
    "mocapbank_test.bvh": "mocapbank", "pybvh_test1.bvh": "cmu",
}
TRUTH_TABLES = {
    "cmu": dict(HipCenter="Hips", Spine="Spine", ShoulderCenter="Neck", Head="Head", Shoulder="{S}Arm",
                Elbow="{S}ForeArm", Wrist="{S}Hand", Hip="{S}UpLeg", Knee="{S}Leg", Ankle="{S}Foot",
                Foot="{S}ToeBase"),
    "mixamo": dict(HipCenter="mixamorig:Hips", Spine="mixamorig:Spine", ShoulderCenter="mixamorig:Neck",
                   Head="mixamorig:Head", Shoulder="mixamorig:{S}Arm", Elbow="mixamorig:{S}ForeArm",
                   Wrist="mixamorig:{S}Hand", Hand="mixamorig:{S}HandMiddle1", Hip="mixamorig:{S}UpLeg",
                   Knee="mixamorig:{S}Leg", Ankle="mixamorig:{S}Foot", Foot="mixamorig:{S}ToeBase"),
    "mocapbank": dict(HipCenter="Hips", Spine="Chest", ShoulderCenter="Neck", Head="Head", Shoulder="{S}Shoulder",
                      Elbow="{S}Elbow", Wrist="{S}Wrist", Hip="{S}Hip", Knee="{S}Knee", Ankle="{S}Ankle",
                      Foot="{S}Ankle_End"),
    "RiggedFigure.glb": dict(HipCenter="torso_joint_1", Spine="torso_joint_2", ShoulderCenter="neck_joint_1",
                             Head="neck_joint_2", Shoulder="arm_joint_{C}_1", Elbow="arm_joint_{C}_2",
                             Wrist="arm_joint_{C}_3", Hip="leg_joint_{C}_1", Knee="leg_joint_{C}_2",
                             Ankle="leg_joint_{C}_3", Foot="leg_joint_{C}_5"),
    "robot_quaternius.glb": dict(HipCenter="Body", Spine="Torso", ShoulderCenter="Neck", Head="Head",
                                 Shoulder="UpperArm.{C}", Elbow="LowerArm.{C}", Wrist="Palm1.{C}",
                                 Hand="Index.{C}", Hip="UpperLeg.{C}",
                                 Knee="LowerLeg.{C}", Ankle="Foot.{C}"),
    # no names: the joint numbers, by the glTF's own node layout (left = the character's left)
    "CesiumMan.glb": dict(HipCenter="joint0", Spine="joint1", ShoulderCenter="joint3", Head="joint4",
                          ShoulderLeft="joint5", ElbowLeft="joint7", WristLeft="joint9", ShoulderRight="joint6",
                          ElbowRight="joint8", WristRight="joint10", HipLeft="joint11", KneeLeft="joint13",
                          AnkleLeft="joint15", FootLeft="joint17", HipRight="joint12", KneeRight="joint14",
                          AnkleRight="joint16", FootRight="joint18"),
}
SOURCES = list(BVH_TRUTH) + ["RiggedFigure.glb", "robot_quaternius.glb", "CesiumMan.glb"]


def truth_names(source) -> dict:
    """Kinect joint -> expected joint name."""
    table = TRUTH_TABLES[BVH_TRUTH.get(source, source)]
    out = {}
    for kj in KINECT20.joints:
        part, side = (kj[:-4], "Left") if kj.endswith("Left") else (kj[:-5], "Right") if kj.endswith("Right") \
            else (kj, "")
        t = table.get(kj) or table.get(part) if side else table.get(kj)
        if t is not None:
            out[kj] = t.format(S=side, C=side[:1])
    return out


@pytest.fixture(scope="module")
def skeletons(data_dir):
    """source -> (skeleton, Kinect joint -> joint index of the expected map)."""
    out = {}
    for source in SOURCES:
        sk = load(data_dir, source)
        out[source] = (sk, {kj: sk.index(n) for kj, n in truth_names(source).items()})
    return out


@pytest.mark.parametrize("source", SOURCES)
def test_every_public_skeleton_maps_as_expected(skeletons, source):
    sk, truth = skeletons[source]
    hmap = sk.map()
    for kj, j in truth.items():
        assert hmap.joints.get(kj) == j, (kj, sk.names[hmap.joints[kj]] if kj in hmap.joints else None, sk.names[j])
    assert not hmap.missing and hmap.drivable
    for kj in KINECT20.joints:                       # what is not mapped is derived: nothing untracked
        assert kj in hmap.joints or kj in hmap.derived, kj
    assert take_map(sk.names, sk.parents, sk.rest) is not None
    _assert_sides(sk, hmap, truth)


def body_frame(sk: Skel, truth: dict, hmap=None) -> tuple[np.ndarray, np.ndarray]:
    """(up, right) of the rest pose from the expected joints alone: up = hips -> head, facing = the toes
    (else the map's own facing, for a skeleton without toes)."""
    up = sk.rest[truth["Head"]] - sk.rest[truth["HipCenter"]]
    up /= np.linalg.norm(up)
    if "FootLeft" in truth:
        toes = sum(sk.rest[truth["Foot" + s]] - sk.rest[truth["Ankle" + s]] for s in ("Left", "Right"))
        toes -= (toes @ up) * up
        facing = toes / np.linalg.norm(toes)
    else:
        facing = hmap.facing
    return up, np.cross(facing, up)


def _assert_sides(sk, hmap, truth):
    """The joints called Left are on the character's left."""
    _, right = body_frame(sk, truth, hmap)
    for part in ("Hip", "Knee", "Ankle", "Shoulder", "Elbow", "Wrist"):
        if part + "Left" in hmap.joints and part + "Right" in hmap.joints:
            d = sk.rest[hmap.joints[part + "Right"]] - sk.rest[hmap.joints[part + "Left"]]
            assert d @ right > 0, part


def test_a_fox_is_no_humanoid(data_dir):
    sk = load(data_dir, "Fox.glb")
    assert take_map(sk.names, sk.parents, sk.rest) is None


# ---- variants -----------------------------------------------------------------------------------------

# Each convention's name per Kinect part ("Collar": the clavicle above the shoulder joint); {S} Left/Right,
# {s} left/right, {C} L/R, {c} l/r. None: the convention has no name for it (the joint gets a meaningless one).
CONVENTIONS = {
    "mixamo": dict(HipCenter="mixamorig:Hips", Spine="mixamorig:Spine", ShoulderCenter="mixamorig:Neck",
                   Head="mixamorig:Head", Collar="mixamorig:{S}Shoulder", Shoulder="mixamorig:{S}Arm",
                   Elbow="mixamorig:{S}ForeArm", Wrist="mixamorig:{S}Hand", Hand="mixamorig:{S}HandMiddle1",
                   Hip="mixamorig:{S}UpLeg", Knee="mixamorig:{S}Leg", Ankle="mixamorig:{S}Foot",
                   Foot="mixamorig:{S}ToeBase"),
    "cmu": dict(HipCenter="Hips", Spine="Spine", ShoulderCenter="Neck", Head="Head", Collar="{S}Shoulder",
                Shoulder="{S}Arm", Elbow="{S}ForeArm", Wrist="{S}Hand", Hand="{S}FingerBase", Hip="{S}UpLeg",
                Knee="{S}Leg", Ankle="{S}Foot", Foot="{S}ToeBase"),
    "vrm": dict(HipCenter="hips", Spine="spine", ShoulderCenter="neck", Head="head", Collar="{s}Shoulder",
                Shoulder="{s}UpperArm", Elbow="{s}LowerArm", Wrist="{s}Hand", Hand="{s}MiddleProximal",
                Hip="{s}UpperLeg", Knee="{s}LowerLeg", Ankle="{s}Foot", Foot="{s}Toes"),
    "blender-dot": dict(HipCenter="hips", Spine="spine", ShoulderCenter="neck", Head="head", Collar="shoulder.{C}",
                        Shoulder="upper_arm.{C}", Elbow="forearm.{C}", Wrist="hand.{C}", Hand="palm.{C}",
                        Hip="thigh.{C}", Knee="shin.{C}", Ankle="foot.{C}", Foot="toe.{C}"),
    "blender-underscore": dict(HipCenter="DEF-hips", Spine="DEF-spine", ShoulderCenter="DEF-neck", Head="DEF-head",
                               Collar="DEF-shoulder_{c}", Shoulder="DEF-upper_arm_{c}", Elbow="DEF-forearm_{c}",
                               Wrist="DEF-hand_{c}", Hand=None, Hip="DEF-thigh_{c}", Knee="DEF-shin_{c}",
                               Ankle="DEF-foot_{c}", Foot="DEF-toe_{c}"),
    "unreal": dict(HipCenter="pelvis", Spine="spine_01", ShoulderCenter="neck_01", Head="head", Collar="clavicle_{c}",
                   Shoulder="upperarm_{c}", Elbow="lowerarm_{c}", Wrist="hand_{c}", Hand="middle_01_{c}",
                   Hip="thigh_{c}", Knee="calf_{c}", Ankle="foot_{c}", Foot="ball_{c}"),
    "daz": dict(HipCenter="hip", Spine="abdomenLower", ShoulderCenter="neckLower", Head="head", Collar="{c}Collar",
                Shoulder="{c}ShldrBend", Elbow="{c}ForearmBend", Wrist="{c}Hand", Hand="{c}Mid1", Hip="{c}ThighBend",
                Knee="{c}Shin", Ankle="{c}Foot", Foot="{c}Toe"),
    "rokoko": dict(HipCenter="Hips", Spine="Spine1", ShoulderCenter="Neck", Head="Head", Collar="{S}Shoulder",
                   Shoulder="{S}Arm", Elbow="{S}ForeArm", Wrist="{S}Hand", Hand="{S}Finger3Metacarpal",
                   Hip="{S}Thigh", Knee="{S}Shin", Ankle="{S}Foot", Foot="{S}Toe"),
    "kinect": dict(HipCenter="SpineBase", Spine="SpineMid", ShoulderCenter="SpineShoulder", Head="Head",
                   Collar=None, Shoulder="Shoulder{S}", Elbow="Elbow{S}", Wrist="Wrist{S}", Hand="Hand{S}",
                   Hip="Hip{S}", Knee="Knee{S}", Ankle="Ankle{S}", Foot="Foot{S}"),
    "openni": dict(HipCenter=None, Spine="Torso", ShoulderCenter="Neck", Head="Head", Collar=None,
                   Shoulder="{S}Shoulder", Elbow="{S}Elbow", Wrist="{S}Hand", Hand=None, Hip="{S}Hip",
                   Knee="{S}Knee", Ankle="{S}Foot", Foot=None),
    "mediapipe": dict(HipCenter=None, Spine=None, ShoulderCenter=None, Head="nose", Collar=None,
                      Shoulder="{s}_shoulder", Elbow="{s}_elbow", Wrist="{s}_wrist", Hand="{s}_index",
                      Hip="{s}_hip", Knee="{s}_knee", Ankle="{s}_ankle", Foot="{s}_foot_index"),
}
CONVENTIONS["mixamo-bare"] = {k: v.replace("mixamorig:", "") for k, v in CONVENTIONS["mixamo"].items()}
TORSO = ("HipCenter", "Spine", "ShoulderCenter", "Head")


def _part(kj):
    for side in ("Left", "Right"):
        if kj.endswith(side):
            return kj[:-len(side)], side
    return kj, ""


def renamed(sk: Skel, truth: dict, convention: dict | None, prefix="node") -> tuple[Skel, dict]:
    """The skeleton with the expected joints named by `convention` (None: every joint meaningless), the
    clavicles (the parent of each shoulder joint below the shoulder centre) too; the others meaningless.
    Returns the skeleton and the Kinect joints the new names speak for."""
    names = [f"{prefix}{j}" for j in range(len(sk.names))]
    spoken = {}
    if convention is not None:
        for kj, j in truth.items():
            part, side = _part(kj)
            template = convention.get(part)
            if template is not None:
                names[j] = template.format(S=side, s=side.lower(), C=side[:1], c=side[:1].lower())
                spoken[kj] = j
            if part == "Shoulder" and convention.get("Collar"):
                collar = sk.parents[j]
                if collar >= 0 and collar not in truth.values():
                    names[collar] = convention["Collar"].format(S=side, s=side.lower(), C=side[:1],
                                                                c=side[:1].lower())
    return Skel(tuple(names), sk.parents, sk.rest), spoken


def removed(sk: Skel, truth: dict, drop) -> tuple[Skel, dict]:
    """The skeleton without the joints `drop` (their children hang from their parent, rest pose kept)."""
    drop = set(drop)
    keep = [j for j in range(len(sk.names)) if j not in drop]
    new = {j: i for i, j in enumerate(keep)}

    def parent(j):
        q = sk.parents[j]
        while q in drop:
            q = sk.parents[q]
        return new[q] if q >= 0 else -1

    out = Skel(tuple(sk.names[j] for j in keep), tuple(parent(j) for j in keep), sk.rest[keep])
    return out, {kj: new[j] for kj, j in truth.items() if j in new}


def ancestors(parents, j):
    out = []
    while j >= 0:
        out.append(j)
        j = parents[j]
    return out


def assert_torso_in_order(sk: Skel, hmap, truth: dict):
    """The torso joints the names do not give lie on the spine in order: hip centre, spine, shoulder centre,
    head, each mapped or derived; the shoulder centre is at or above where both arms branch off."""
    w = hmap.weights()
    pos = {kj: w[KINECT20.index(kj)] @ sk.rest for kj in TORSO if kj in hmap.joints or kj in hmap.derived}
    assert set(pos) == set(TORSO), set(TORSO) - set(pos)
    head_line = ancestors(sk.parents, truth["Head"])
    for kj in TORSO:
        if kj in hmap.joints:
            j = hmap.joints[kj]
            # without names a head and its top end look like a neck and a head: the head may be one up
            assert j in head_line or kj == "Head" and sk.parents[j] == truth["Head"], (kj, sk.names[j])
    up, _ = body_frame(sk, truth, hmap)
    height = np.ptp(sk.rest @ up)
    along = [pos[kj] @ up for kj in TORSO]
    assert all(b > a - 0.02 * height for a, b in zip(along, along[1:])), dict(zip(TORSO, along))
    arms = ancestors(sk.parents, truth["ShoulderLeft"])
    branch = next(j for j in ancestors(sk.parents, truth["ShoulderRight"]) if j in arms)
    if "ShoulderCenter" in hmap.joints:
        assert branch in ancestors(sk.parents, hmap.joints["ShoulderCenter"]), sk.names[hmap.joints["ShoulderCenter"]]


def assert_maps_like(sk: Skel, hmap, truth: dict, spoken: dict, exact=()):
    """Limbs exactly as expected; the torso joints named by the convention exactly, the others in order.
    A joint outside the body's tree (an IK foot hung from the scene root) is found only by its name."""
    astray = {kj for kj, j in truth.items() if kj not in spoken and truth["HipCenter"] not in ancestors(sk.parents, j)}
    for kj in LIMB_JOINTS + [kj for kj in spoken if kj in TORSO] + list(exact):
        if kj in truth and kj not in astray:
            got = hmap.joints.get(kj)
            assert got == truth[kj], (kj, sk.names[got] if got is not None else None, sk.names[truth[kj]])
    assert_torso_in_order(sk, hmap, truth)
    for kj in ("HandLeft", "HandRight", "FootLeft", "FootRight"):
        if kj in truth and kj in spoken:
            assert hmap.joints.get(kj) == truth[kj], kj
    _assert_sides(sk, hmap, truth)
    assert set(hmap.missing) <= astray and hmap.drivable


@pytest.mark.parametrize("convention", list(CONVENTIONS))
@pytest.mark.parametrize("source", SOURCES)
def test_renamed_to_each_convention(skeletons, source, convention):
    sk, truth = skeletons[source]
    other, spoken = renamed(sk, truth, CONVENTIONS[convention])
    hmap = other.map()
    assert_maps_like(other, hmap, truth, spoken)
    assert take_map(other.names, other.parents, other.rest) is not None


@pytest.mark.parametrize("source", SOURCES)
def test_meaningless_names_topology_and_geometry_alone(skeletons, source):
    sk, truth = skeletons[source]
    other, _ = renamed(sk, truth, None)
    hmap = other.map()
    assert set(hmap.how.values()) <= {"topology", "geometry"}
    assert_maps_like(other, hmap, truth, {}, exact=("HipCenter",))


def spine_line(sk: Skel, truth: dict) -> list[int]:
    """The joints from the hip centre up to the head, in order."""
    return ancestors(sk.parents, truth["Head"])[::-1][ancestors(sk.parents, truth["Head"])[::-1]
                                                      .index(truth["HipCenter"]):]


def arm_branch(sk: Skel, truth: dict) -> int:
    arms = ancestors(sk.parents, truth["ShoulderLeft"])
    return next(j for j in ancestors(sk.parents, truth["ShoulderRight"]) if j in arms)


def without_neck(sk, truth):
    """Every joint between where the arms branch off and the head."""
    line = spine_line(sk, truth)
    return [j for j in line[line.index(arm_branch(sk, truth)) + 1:] if j != truth["Head"]]


def without_spine(sk, truth):
    """Every joint between the hip centre and where the arms branch off."""
    line = spine_line(sk, truth)
    return line[1:line.index(arm_branch(sk, truth))]


NAMED = ["mixamo", "unreal", "daz", "kinect"]


@pytest.mark.parametrize("cut", ["neck", "spine", "neck and spine"])
@pytest.mark.parametrize("convention", NAMED + [None])
@pytest.mark.parametrize("source", SOURCES)
def test_neck_or_spine_removed(skeletons, source, convention, cut):
    sk, truth = skeletons[source]
    drop = (without_neck(sk, truth) if "neck" in cut else []) + (without_spine(sk, truth) if "spine" in cut else [])
    if not drop:
        pytest.skip(f"{source} has no {cut} joint to remove")
    short, truth = removed(sk, truth, drop)
    other, spoken = renamed(short, truth, None if convention is None else CONVENTIONS[convention])
    hmap = other.map()
    # the torso joints left move up or down to where the arms branch: only the hips and head stay exact
    limbs = {kj: j for kj, j in spoken.items() if kj not in TORSO}
    assert_maps_like(other, hmap, truth, limbs, exact=("HipCenter", "Head") if convention else ("HipCenter",))
    for kj in TORSO:                                 # what the cut took is derived between its neighbours
        assert kj in hmap.joints or kj in hmap.derived
    assert take_map(other.names, other.parents, other.rest) is not None


@pytest.mark.parametrize("convention", NAMED)
@pytest.mark.parametrize("source", SOURCES)
def test_elbows_removed_drive_what_maps_and_report_the_rest(skeletons, source, convention):
    sk, truth = skeletons[source]
    short, truth = removed(sk, truth, [truth["ElbowLeft"], truth["ElbowRight"]])
    other, spoken = renamed(short, truth, CONVENTIONS[convention])
    hmap = other.map()
    assert hmap.missing == ("ElbowLeft", "ElbowRight") and "ElbowLeft" in hmap.unmapped
    for kj in ("ShoulderLeft", "WristLeft", "ShoulderRight", "WristRight", "HipLeft", "AnkleRight"):
        assert hmap.joints[kj] == truth[kj], kj
    assert hmap.drivable and {"arm left", "arm right", "leg left", "leg right"} <= set(hmap.limbs)
    assert "not mapped (untracked): ElbowLeft, ElbowRight" in "\n".join(hmap.describe())


@pytest.mark.parametrize("source", SOURCES)
def test_hands_straight_off_the_chest(skeletons, source):
    """A chibi: no collar, shoulder or elbow, the hand hangs from the chest."""
    sk, truth = skeletons[source]
    branch = arm_branch(sk, truth)
    drop = [j for s in ("Left", "Right") for j in ancestors(sk.parents, truth["Wrist" + s])
            if j != truth["Wrist" + s] and branch in ancestors(sk.parents, j) and j != branch]
    short, truth = removed(sk, truth, drop)
    other, spoken = renamed(short, truth, CONVENTIONS["mixamo"])
    hmap = other.map()
    assert set(hmap.missing) == {"ShoulderLeft", "ElbowLeft", "ShoulderRight", "ElbowRight"}
    assert hmap.joints["WristLeft"] == truth["WristLeft"] and hmap.joints["WristRight"] == truth["WristRight"]
    assert hmap.joints["HipCenter"] == truth["HipCenter"] and hmap.drivable
    # the shoulder centre is where the hands branch off, the spine between it and the hips
    assert hmap.joints["ShoulderCenter"] in spine_line(other, truth)


def mirrored(sk: Skel) -> Skel:
    """The rest pose reflected through the body's plane of symmetry (x -> -x in the character's frame)."""
    return Skel(sk.names, sk.parents, sk.rest * [-1.0, 1.0, 1.0])


def swap(kj: str) -> str:
    return kj[:-4] + "Right" if kj.endswith("Left") else kj[:-5] + "Left" if kj.endswith("Right") else kj


@pytest.mark.parametrize("source", [s for s in SOURCES if s != "pybvh_test1.bvh"])
def test_mirrored_names_that_lie_lose_to_the_feet(skeletons, source):
    """Reflected, the joints named left stand on the right. Where the toes say which way the body faces,
    geometry wins and the sides are swapped (and said); a body without toes keeps its names."""
    sk, truth = skeletons[source]
    other, spoken = renamed(sk, truth, CONVENTIONS["mixamo"])
    flipped = mirrored(other)
    hmap = flipped.map()
    toes = "FootLeft" in truth and truth["AnkleLeft"] in ancestors(sk.parents, truth["FootLeft"])
    expect = {swap(kj): j for kj, j in truth.items()} if toes else truth
    for kj in LIMB_JOINTS:
        assert hmap.joints.get(kj) == expect[kj], kj
    assert any("mirrored" in line for line in hmap.describe()) == toes
    if toes:
        assert hmap.how["ShoulderLeft"] == hmap.how["HipRight"] == "geometry"
        _assert_sides(flipped, hmap, expect)
    # without names, the reflected body's own left is found
    anonymous, _ = renamed(mirrored(sk), truth, None)
    hmap = anonymous.map()
    for kj in ("ShoulderLeft", "WristLeft", "HipLeft", "AnkleLeft", "ShoulderRight", "HipRight"):
        if toes:
            assert hmap.joints[kj] == truth[swap(kj)], kj


# ---- a BVH walk without a neck drives an avatar ------------------------------------------------------

def bvh_text(clip, keep: list[int], rename: dict) -> str:
    """BVH text of `clip` with only the joints `keep` (a removed joint's offset passes to its children, its
    rotation is lost), renamed by `rename`."""
    keep = sorted(keep)
    kept = set(keep)
    parent = {}
    for j in keep:
        q = clip.parents[j]
        while q >= 0 and q not in kept:
            q = clip.parents[q]
        parent[j] = q
    rest = rest_positions(clip)
    columns, starts, at = [], {}, 0
    for j, ch in enumerate(clip.channels):
        starts[j], at = at, at + len(ch)
    lines = ["HIERARCHY"]

    def write(j, depth):
        pad = "  " * depth
        off = rest[j] - (rest[parent[j]] if parent[j] >= 0 else 0.0)
        kids = [c for c in keep if parent[c] == j]
        if clip.end_sites[j]:
            lines.extend([f"{pad}End Site", f"{pad}{{", f"{pad}  OFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}",
                          f"{pad}}}"])
            return
        lines.append(f"{pad}{'ROOT' if parent[j] < 0 else 'JOINT'} {rename.get(clip.names[j], clip.names[j])}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}")
        ch = clip.channels[j]
        lines.append(f"{pad}  CHANNELS {len(ch)} " + " ".join(c[0].upper() + c[1:] for c in ch))
        columns.extend(range(starts[j], starts[j] + len(ch)))
        for c in kids:
            write(c, depth + 1)
        lines.append(f"{pad}}}")

    for j in keep:
        if parent[j] < 0:
            write(j, 0)
    motion = clip.motion[:, columns]
    lines += ["MOTION", f"Frames: {len(motion)}", f"Frame Time: {clip.frame_time:.6f}"]
    lines += [" ".join(f"{v:.4f}" for v in row) for row in motion]
    return "\n".join(lines) + "\n"


# The plain Mixamo-named walk: no neck, no lower back, no hip joints, a thumb as the only finger.
NECKLESS = ["Hips", "Spine", "Head", "Head_End", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LThumb",
            "LThumb_End", "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RThumb", "RThumb_End",
            "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "LeftToeBase_End", "RightUpLeg", "RightLeg",
            "RightFoot", "RightToeBase", "RightToeBase_End"]


@pytest.fixture(scope="module")
def neckless_walk(data_dir, tmp_path_factory):
    clip = parse_bvh((data_dir / "bvh" / "cmu_12_01_walk.bvh").read_text())
    text = bvh_text(clip, [clip.names.index(n) for n in NECKLESS],
                    {"LThumb": "LeftHandThumb1", "RThumb": "RightHandThumb1"})
    path = tmp_path_factory.mktemp("neckless") / "walk.bvh"
    path.write_text(text)
    return path


def test_a_mixamo_walk_without_a_neck_maps(neckless_walk):
    clip = parse_bvh(neckless_walk.read_text())
    assert {"Hips", "Spine", "Head", "LeftHandThumb1"} <= set(clip.names)
    assert clip.parents[clip.names.index("Head")] == clip.names.index("Spine") and "Neck" not in clip.names
    hmap = take_map(clip.names, clip.parents, rest_positions(clip))
    assert hmap is not None and not hmap.missing and not hmap.unmapped
    name = lambda kj: clip.names[hmap.joints[kj]]  # noqa: E731
    assert (name("HipCenter"), name("ShoulderCenter"), name("Head")) == ("Hips", "Spine", "Head")
    assert (name("ShoulderLeft"), name("ElbowLeft"), name("WristLeft")) == ("LeftArm", "LeftForeArm", "LeftHand")
    # the thumb is no hand: the hand extends the forearm; the spine is derived between hips and chest
    assert "HandLeft" in hmap.derived and "Spine" in hmap.derived


@pytest.mark.slow
def test_a_mixamo_walk_without_a_neck_drives_an_avatar(neckless_walk, tmp_path, capsys, data_dir):
    from kinetre.cli import main
    from kinetre.motion.bvh import load_bvh
    out = tmp_path / "figure.bvh"
    code = main(["avatar", str(data_dir / "avatars" / "RiggedFigure.glb"), "--motion", str(neckless_walk),
                 "-o", str(out), "--max-frames", "30"])
    text, err = capsys.readouterr()
    assert code == 0, err
    moved = load_bvh(out, as_kinect=False)
    assert moved.positions.shape[0] == 30
    # the avatar walks: its root travels and its knees swing
    travel = np.linalg.norm(moved.positions[-1, 0] - moved.positions[0, 0])
    assert travel > 0.1 * np.ptp(moved.positions[0, :, 1])


def test_nothing_to_drive_is_refused_clearly():
    """A chain of joints with no limbs and no root the mapper can find."""
    names, parents = ("a", "b", "c"), (-1, 0, 1)
    rest = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 2.0, 0.0]])
    hmap = map_humanoid(names, parents, rest)
    assert not hmap.drivable and take_map(names, parents, rest) is None


def test_docstring_examples():
    import doctest

    import kinetre.rotation
    import kinetre.skeleton.humanoid_map
    for module in (kinetre.skeleton.humanoid_map, kinetre.rotation):
        result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
        assert result.attempted > 0 and result.failed == 0, module.__name__


@pytest.mark.slow
@pytest.mark.parametrize("name", ["RiggedFigure.glb", "robot_quaternius.glb", "CesiumMan.glb"])
def test_an_avatar_and_its_own_animations_map_alike(data_dir, name):
    """One skeleton, one map: the avatar's bone map and the map its animations are read by agree."""
    from kinetre.avatar.bonemap import map_bones
    from kinetre.motion.gltf import animation_skeleton
    avatar = load_avatar(data_dir / "avatars" / name)
    as_avatar = map_bones(avatar)
    names, parents, rest, tips = animation_skeleton(data_dir / "avatars" / name)
    as_motion = take_map(names, parents, rest, tips=tips)
    assert as_motion is not None
    assert as_motion.joints.keys() == as_avatar.joints.keys() and as_motion.derived.keys() == as_avatar.derived.keys()
    # the same joints (unnamed nodes are named differently by the two readers: compare where they stand)
    size = np.ptp(avatar.bind_positions, axis=0).max()
    for kj, j in as_avatar.joints.items():
        np.testing.assert_allclose(rest[as_motion.joints[kj]], avatar.bind_positions[j], atol=1e-3 * size, err_msg=kj)


def test_a_take_that_kept_its_own_bones_drives_an_avatar(data_dir):
    from kinetre.avatar.bonemap import kinect_take
    from kinetre.motion.bvh import load_bvh
    own = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh", as_kinect=False)
    mapped = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    tracked = own.tracked.copy()
    tracked[5, own.model.joints.index("LeftForeArm")] = False    # a joint lost in one frame
    own = type(own)(own.model, own.positions, tracked, own.fps, own.source)
    take = kinect_take(own)
    assert take.model.name == "kinect20"
    np.testing.assert_allclose(take.positions[0], mapped.positions[0], atol=1e-9)   # the file's up is +Y
    assert not take.tracked[5, KINECT20.index("ElbowLeft")] and take.tracked[5].sum() == 19
    assert take.tracked[4].all()
