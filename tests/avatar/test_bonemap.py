"""Bone maps: by name, by geometry (the same answer without names), saved JSON, and refusals."""
from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest

from kinetre.avatar.bonemap import REQUIRED, UP, map_bones, map_path, read_map, write_map
from kinetre.avatar.load import load_avatar
from kinetre.errors import BadAvatarError

from avatar.conftest import HUMANOIDS


@pytest.mark.slow
@pytest.mark.parametrize("name", HUMANOIDS)
def test_every_humanoid_maps_completely_with_left_on_the_left(rigged, name):
    avatar, bonemap, _ = rigged[name]
    assert not bonemap.missing
    p = avatar.bind_positions
    right = np.cross(bonemap.facing, UP)
    for part in ("Hip", "Knee", "Ankle", "Shoulder", "Elbow", "Wrist"):
        j = bonemap.joints
        assert (p[j[part + "Right"]] - p[j[part + "Left"]]) @ right > 0, part
    # the facing agrees with the feet: toes point forward
    j = bonemap.joints
    if "FootLeft" in j:
        toe = p[j["FootLeft"]] - p[j["AnkleLeft"]]
        assert toe @ bonemap.facing > 0


def test_cesium_man_has_no_joint_names_and_is_mapped_by_geometry(rigged):
    avatar, bonemap, _ = rigged["CesiumMan"]
    assert all(n.startswith("joint") for n in avatar.joint_names)
    assert set(bonemap.how.values()) == {"geometry"}
    # it faces +X in its bind pose (its feet say so)
    np.testing.assert_allclose(bonemap.facing, [1, 0, 0], atol=1e-3)


def test_geometry_alone_finds_what_the_names_find(rigged):
    avatar, named, _ = rigged["RiggedFigure"]
    anonymous = dataclasses.replace(avatar, joint_names=tuple(f"joint{k}" for k in range(len(avatar.joints))),
                                    source="/nonexistent/anonymous.glb")
    found = map_bones(anonymous)
    assert set(found.how.values()) == {"geometry"}
    for kj in REQUIRED:
        assert found.joints[kj] == named.joints[kj], kj


def test_a_fox_is_refused_and_pointed_to_possession(data_dir):
    fox = load_avatar(data_dir / "avatars" / "Fox.glb")
    with pytest.raises(BadAvatarError, match=r"Fox.glb: not an upright humanoid.*kinetre animate"):
        map_bones(fox)


def test_an_armless_avatar_is_driven_by_what_maps_and_a_flat_one_is_refused(rigged):
    avatar, bonemap, _ = rigged["CesiumMan"]
    parents = avatar.joint_parents.copy()
    for side in ("Left", "Right"):
        parents[bonemap.joints["Shoulder" + side]] = -1           # the arms torn off
    armless = map_bones(dataclasses.replace(avatar, joint_parents=parents, source="/nonexistent/armless.glb"))
    assert armless.missing == ("ShoulderLeft", "ElbowLeft", "WristLeft", "ShoulderRight", "ElbowRight", "WristRight")
    for kj in ("HipCenter", "Spine", "Head", "HipLeft", "KneeLeft", "AnkleLeft", "HipRight", "AnkleRight"):
        assert armless.joints[kj] == bonemap.joints[kj], kj
    flat = dataclasses.replace(avatar, joint_parents=np.full_like(parents, -1), source="/nonexistent/flat.glb")
    with pytest.raises(BadAvatarError, match=r"flat.glb: cannot map the skeleton to a body: no joint found for "
                       r"HipCenter, ShoulderCenter, .* \(mapped: nothing\)"):
        map_bones(flat)


def test_a_saved_map_next_to_the_avatar_is_loaded_and_wins(tmp_path, data_dir, rigged):
    copy = tmp_path / "figure.glb"
    shutil.copy(data_dir / "avatars" / "RiggedFigure.glb", copy)
    avatar = load_avatar(copy)
    auto = map_bones(avatar)
    table = dict(auto.joints)
    table["Head"] = table["ShoulderCenter"]                       # a (silly) hand correction
    del table["ShoulderCenter"]
    table["ShoulderCenter"] = avatar.joint_names.index("torso_joint_3")
    write_map(map_path(str(copy)), avatar, table)
    assert read_map(map_path(str(copy)), avatar) == table
    again = map_bones(avatar)
    assert again.joints["ShoulderCenter"] == table["ShoulderCenter"] and again.how["ShoulderCenter"] == "file"
    (tmp_path / "bad.json").write_text('{"kinect20": {"Elbow": "torso_joint_1"}}')
    with pytest.raises(BadAvatarError, match="bad.json: 'Elbow' is not a Kinect-20 joint"):
        map_bones(avatar, str(tmp_path / "bad.json"))


# RiggedFigure's joints renamed after common rigs: (its joint name, Mixamo, Unreal, VRoid)
SCHEMES = [
    ("torso_joint_1", "mixamorig:Hips", "pelvis", "J_Bip_C_Hips"),
    ("torso_joint_2", "mixamorig:Spine", "spine_01", "J_Bip_C_Spine"),
    ("torso_joint_3", "mixamorig:Spine2", "spine_03", "J_Bip_C_Chest"),
    ("neck_joint_1", "mixamorig:Neck", "neck_01", "J_Bip_C_Neck"),
    ("neck_joint_2", "mixamorig:Head", "head", "J_Bip_C_Head"),
    ("arm_joint_L_1", "mixamorig:LeftArm", "upperarm_l", "J_Bip_L_UpperArm"),
    ("arm_joint_L_2", "mixamorig:LeftForeArm", "lowerarm_l", "J_Bip_L_LowerArm"),
    ("arm_joint_L_3", "mixamorig:LeftHand", "hand_l", "J_Bip_L_Hand"),
    ("arm_joint_R_1", "mixamorig:RightArm", "upperarm_r", "J_Bip_R_UpperArm"),
    ("arm_joint_R_2", "mixamorig:RightForeArm", "lowerarm_r", "J_Bip_R_LowerArm"),
    ("arm_joint_R_3", "mixamorig:RightHand", "hand_r", "J_Bip_R_Hand"),
    ("leg_joint_L_1", "mixamorig:LeftUpLeg", "thigh_l", "J_Bip_L_UpperLeg"),
    ("leg_joint_L_2", "mixamorig:LeftLeg", "calf_l", "J_Bip_L_LowerLeg"),
    ("leg_joint_L_3", "mixamorig:LeftFoot", "foot_l", "J_Bip_L_Foot"),
    ("leg_joint_L_5", "mixamorig:LeftToeBase", "ball_l", "J_Bip_L_ToeBase"),
    ("leg_joint_R_1", "mixamorig:RightUpLeg", "thigh_r", "J_Bip_R_UpperLeg"),
    ("leg_joint_R_2", "mixamorig:RightLeg", "calf_r", "J_Bip_R_LowerLeg"),
    ("leg_joint_R_3", "mixamorig:RightFoot", "foot_r", "J_Bip_R_Foot"),
    ("leg_joint_R_5", "mixamorig:RightToeBase", "ball_r", "J_Bip_R_ToeBase"),
]
VRM_BONES = {"torso_joint_1": "hips", "torso_joint_2": "spine", "torso_joint_3": "chest", "neck_joint_1": "neck",
             "neck_joint_2": "head", "arm_joint_L_1": "leftUpperArm", "arm_joint_L_2": "leftLowerArm",
             "arm_joint_L_3": "leftHand", "arm_joint_R_1": "rightUpperArm", "arm_joint_R_2": "rightLowerArm",
             "arm_joint_R_3": "rightHand", "leg_joint_L_1": "leftUpperLeg", "leg_joint_L_2": "leftLowerLeg",
             "leg_joint_L_3": "leftFoot", "leg_joint_L_5": "leftToes", "leg_joint_R_1": "rightUpperLeg",
             "leg_joint_R_2": "rightLowerLeg", "leg_joint_R_3": "rightFoot", "leg_joint_R_5": "rightToes"}


def renamed(data_dir, tmp_path, rename, suffix=".glb", extensions=None):
    """RiggedFigure with its nodes renamed (and VRM extensions added), written to tmp_path."""
    import pygltflib
    doc = pygltflib.GLTF2.load(str(data_dir / "avatars" / "RiggedFigure.glb"))
    nodes = {}
    for i, node in enumerate(doc.nodes):
        nodes[node.name] = i
        node.name = rename(node.name, i)
    if extensions:
        doc.extensions = extensions(nodes)
        doc.extensionsUsed = list(doc.extensions)
    path = tmp_path / f"figure{suffix}"
    doc.save_binary(str(path))
    return load_avatar(path)


@pytest.mark.parametrize("scheme", [1, 2, 3], ids=["mixamo", "unreal", "vroid"])
def test_common_rig_names_map_like_the_original(rigged, data_dir, tmp_path, scheme):
    avatar, reference, _ = rigged["RiggedFigure"]
    table = {row[0]: row[scheme] for row in SCHEMES}
    other = renamed(data_dir, tmp_path, lambda name, i: table.get(name, f"node{i}"))
    found = map_bones(other)
    for kj, j in reference.joints.items():
        assert found.joints[kj] == j, (kj, other.joint_names[found.joints[kj]], avatar.joint_names[j])
        assert found.how[kj] == "name", kj


@pytest.mark.parametrize("version", ["0.x", "1.0"])
def test_a_vrm_humanoid_maps_by_its_human_bones(rigged, data_dir, tmp_path, version):
    avatar, reference, _ = rigged["RiggedFigure"]

    def extensions(nodes):
        if version == "0.x":
            return {"VRM": {"humanoid": {"humanBones": [{"bone": b, "node": nodes[n]} for n, b in VRM_BONES.items()]}}}
        return {"VRMC_vrm": {"specVersion": "1.0", "humanoid": {"humanBones": {b: {"node": nodes[n]}
                                                                              for n, b in VRM_BONES.items()}}}}
    vrm = renamed(data_dir, tmp_path, lambda name, i: f"bone{i}", ".vrm", extensions)
    assert len(vrm.vrm_bones) == len(VRM_BONES)
    found = map_bones(vrm)
    for kj, j in reference.joints.items():
        assert found.joints[kj] == j and found.how[kj] == "vrm", kj
