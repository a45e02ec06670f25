"""The skeleton mapper on every public BVH and avatar, and on variants made from their skeletons: renamed to
each rig convention, given meaningless names, with the neck, spine or elbows removed, and mirrored."""
from __future__ import annotations

import dataclasses
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
    "mocapbank_test.bvh": "mocapbank", "pybvh_test1.bvh": "pybvh",
}
_LR = {"Left": "Left", "Right": "Right"}
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
    "pybvh": dict(HipCenter="Hips", Spine="Spine", ShoulderCenter="Neck", Head="Head", Shoulder="{S}Arm",
                  Elbow="{S}ForeArm", Wrist="{S}Hand", Hip="{S}UpLeg", Knee="{S}Leg", Ankle="{S}Foot",
                  Foot="{S}ToeBase"),
    "RiggedFigure.glb": dict(HipCenter="torso_joint_1", Spine="torso_joint_2", ShoulderCenter="neck_joint_1",
                             Head="neck_joint_2", Shoulder="arm_joint_{C}_1", Elbow="arm_joint_{C}_2",
                             Wrist="arm_joint_{C}_3", Hip="leg_joint_{C}_1", Knee="leg_joint_{C}_2",
                             Ankle="leg_joint_{C}_3", Foot="leg_joint_{C}_5"),
    "robot_quaternius.glb": dict(HipCenter="Body", Spine="Torso", ShoulderCenter="Neck", Head="Head",
                                 Shoulder="UpperArm.{C}", Elbow="LowerArm.{C}", Hip="UpperLeg.{C}",
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
    "mixamo-bare": dict(HipCenter="Hips", Spine="Spine", ShoulderCenter="Neck", Head="Head", Collar="{S}Shoulder",
                        Shoulder="{S}Arm", Elbow="{S}ForeArm", Wrist="{S}Hand", Hand="{S}HandMiddle1",
                        Hip="{S}UpLeg", Knee="{S}Leg", Ankle="{S}Foot", Foot="{S}ToeBase"),
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
            assert hmap.joints[kj] in head_line, (kj, sk.names[hmap.joints[kj]])
    up, _ = body_frame(sk, truth, hmap)
    height = np.ptp(sk.rest @ up)
    along = [pos[kj] @ up for kj in TORSO]
    assert all(b > a - 0.02 * height for a, b in zip(along, along[1:])), dict(zip(TORSO, along))
    arms = ancestors(sk.parents, truth["ShoulderLeft"])
    branch = next(j for j in ancestors(sk.parents, truth["ShoulderRight"]) if j in arms)
    if "ShoulderCenter" in hmap.joints:
        assert branch in ancestors(sk.parents, hmap.joints["ShoulderCenter"]), sk.names[hmap.joints["ShoulderCenter"]]


def assert_maps_like(sk: Skel, hmap, truth: dict, spoken: dict, exact=()):
    """Limbs exactly as expected; the torso joints named by the convention exactly, the others in order."""
    for kj in LIMB_JOINTS + [kj for kj in spoken if kj in TORSO] + list(exact):
        if kj in truth:
            got = hmap.joints.get(kj)
            assert got == truth[kj], (kj, sk.names[got] if got is not None else None, sk.names[truth[kj]])
    assert_torso_in_order(sk, hmap, truth)
    for kj in ("HandLeft", "HandRight", "FootLeft", "FootRight"):
        if kj in truth and kj in spoken:
            assert hmap.joints.get(kj) == truth[kj], kj
    _assert_sides(sk, hmap, truth)
    assert not hmap.missing and hmap.drivable


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
    # a joint outside the body's tree (an IK foot hung from the scene root) can only be found by its name
    body = {kj: j for kj, j in truth.items() if truth["HipCenter"] in ancestors(sk.parents, j)}
    if len(body) < len(truth):
        hmap = dataclasses.replace(hmap, joints={**hmap.joints, **{kj: j for kj, j in truth.items() if kj not in body}})
    assert_maps_like(other, hmap, truth, {}, exact=("HipCenter",))
