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


def test_a_map_that_cannot_be_completed_names_the_missing_joints(rigged):
    avatar, bonemap, _ = rigged["CesiumMan"]
    parents = avatar.joint_parents.copy()
    for side in ("Left", "Right"):
        parents[bonemap.joints["Shoulder" + side]] = -1           # the arms torn off
    armless = dataclasses.replace(avatar, joint_parents=parents, source="/nonexistent/armless.glb")
    with pytest.raises(BadAvatarError, match=r"no joint found for ShoulderCenter, ShoulderLeft, ElbowLeft, WristLeft, "
                       r"ShoulderRight, ElbowRight, WristRight \(mapped: HipCenter"):
        map_bones(armless)


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
