"""BVH parsing, forward kinematics, units, the Kinect-20 map and every bad-input message."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kinetre
from kinetre.errors import BadMotionError
from kinetre.motion.bvh import detect_unit, forward_kinematics, kinect_map, load_bvh, parse_bvh
from kinetre.rotation import up_rotation

BVH_FILES = ["cmu_01_01_hops.bvh", "cmu_12_01_walk.bvh", "mixamo_rig_freebvh.bvh", "mocapbank_test.bvh",
             "pybvh_test1.bvh"]


def chain(order: str, values: str, child_channels: str = "", child_values: str = "") -> str:
    """A root with position + rotation channels in `order`, a child 1 unit along +X, and an End Site."""
    rot = " ".join(f"{a}rotation" for a in order)
    cc = f"CHANNELS {len(child_channels.split())} {child_channels}" if child_channels else ""
    return f"""HIERARCHY
ROOT Root
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition {rot}
  JOINT Child
  {{
    OFFSET 1 0 0
    {cc}
    End Site
    {{
      OFFSET 0 2 0
    }}
  }}
}}
MOTION
Frames: 1
Frame Time: 0.04
0 0 0 {values} {child_values}
"""


@pytest.fixture(scope="module")
def takes(data_dir):
    return {name: load_bvh(data_dir / "bvh" / name) for name in BVH_FILES}


@pytest.mark.parametrize("name", BVH_FILES)
def test_every_shared_bvh_maps_to_kinect_with_a_human_height(takes, name):
    take = takes[name]
    assert take.model == kinetre.KINECT20
    assert np.isfinite(take.positions).all() and take.tracked.all()
    first = take.frame(0)
    assert 1.2 <= first.height <= 2.2, f"{name}: height {first.height:.2f} m"
    # +Y up: the head is above the hips, the hips above the ankles
    p = first.positions
    j = kinetre.KINECT20.index
    assert p[j("Head"), 1] > p[j("HipCenter"), 1] > max(p[j("AnkleLeft"), 1], p[j("AnkleRight"), 1])
    # the feet touch the ground region: lowest joint within 25 cm of y = 0 (files stand on their floor)
    assert -0.25 < take.positions[..., 1].min() < 0.25


@pytest.mark.parametrize("name", BVH_FILES)
def test_limbs_move_over_time(takes, name):
    take = takes[name]
    j = kinetre.KINECT20.index
    for joint in ("WristLeft", "WristRight", "AnkleLeft", "AnkleRight"):
        rel = take.positions[:, j(joint)] - take.positions[:, j("HipCenter")]
        travel = np.linalg.norm(rel - rel[0], axis=1).max()
        assert travel > 0.05, f"{name}: {joint} moves only {travel:.3f} m relative to the hips"


def test_walk_and_hops_travel(takes):
    # the CMU walk crosses the room; the hops go forward and back: the root moves metres
    for name in ("cmu_12_01_walk.bvh", "cmu_01_01_hops.bvh"):
        root = takes[name].positions[:, 0]
        assert np.linalg.norm(np.ptp(root[:, [0, 2]], axis=0)) > 1.0
    hops = takes["cmu_01_01_hops.bvh"].positions[:, 0, 1]
    assert np.ptp(hops) > 0.25  # jumps: the hips rise and fall by more than 25 cm


def test_frame_rates(takes):
    assert takes["cmu_12_01_walk.bvh"].fps == pytest.approx(120.0, rel=1e-3)
    assert takes["mixamo_rig_freebvh.bvh"].fps == pytest.approx(30.0, rel=1e-3)
    assert len(takes["cmu_01_01_hops.bvh"]) == 2752


def test_cmu_map_skips_the_zero_length_hip_joints(data_dir):
    clip = parse_bvh((data_dir / "bvh" / "cmu_12_01_walk.bvh").read_text(), "walk")
    _, drivers = kinect_map(clip.names, clip.parents)
    assert drivers["HipLeft"] == "LeftUpLeg" and drivers["ShoulderCenter"] == "Neck"
    assert drivers["ShoulderLeft"] == "LeftArm" and drivers["FootRight"] == "RightToeBase"


def test_mixamo_prefix_and_mocapbank_names(data_dir):
    clip = parse_bvh((data_dir / "bvh" / "mixamo_rig_freebvh.bvh").read_text(), "mixamo")
    _, drivers = kinect_map(clip.names, clip.parents)
    assert drivers["ShoulderLeft"] == "mixamorig:LeftArm"  # not the clavicle, mixamorig:LeftShoulder
    clip = parse_bvh((data_dir / "bvh" / "mocapbank_test.bvh").read_text(), "mocapbank")
    _, drivers = kinect_map(clip.names, clip.parents)
    assert drivers["ShoulderLeft"] == "LeftShoulder" and drivers["HandLeft"] == "LeftWrist_End"


def test_z_up_file_is_turned_to_y_up(takes, data_dir):
    # pybvh_test1 stands along +Z in the file (spine offsets along z)
    clip = parse_bvh((data_dir / "bvh" / "pybvh_test1.bvh").read_text(), "pybvh")
    fk = forward_kinematics(clip)
    head = clip.names.index("Head")
    assert fk[0, head, 2] - fk[0, 0, 2] > 15  # file units (inches): head 15+ above hips along z
    take = takes["pybvh_test1.bvh"]
    j = kinetre.KINECT20.index
    assert take.positions[0, j("Head"), 1] - take.positions[0, j("HipCenter"), 1] > 0.4


@pytest.mark.parametrize("order", ["XYZ", "ZYX", "YXZ"])
def test_rotation_order_matches_analytic_euler(order):
    angles = {"X": 30.0, "Y": -50.0, "Z": 70.0}
    values = " ".join(str(angles[a]) for a in order)
    clip = parse_bvh(chain(order, values), "chain")
    pos = forward_kinematics(clip)[0]
    # intrinsic rotations in channel order: R = R_a1 R_a2 R_a3 (scipy: upper-case = intrinsic)
    r = Rotation.from_euler(order, [angles[a] for a in order], degrees=True).as_matrix()
    np.testing.assert_allclose(pos[1], r @ [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(pos[2], r @ [1, 0, 0] + r @ [0, 2, 0], atol=1e-12)
    assert clip.names == ("Root", "Child", "Child_End")


def test_orders_differ():
    a = forward_kinematics(parse_bvh(chain("XYZ", "30 -50 70"), "a"))[0, 2]
    b = forward_kinematics(parse_bvh(chain("ZYX", "70 -50 30"), "b"))[0, 2]
    assert np.linalg.norm(a - b) > 0.1


def test_position_channels_on_a_child_replace_its_offset():
    text = chain("ZYX", "90 0 0", "Xposition Yposition Zposition Zrotation", "0 3 0 0")
    pos = forward_kinematics(parse_bvh(text, "pos"))[0]
    # root turned 90° about Z: the child's local translation (0, 3, 0) lands at (-3, 0, 0)
    np.testing.assert_allclose(pos[1], [-3.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pos[2], [-3.0 - 2.0, 0.0, 0.0], atol=1e-12)


def test_root_translation_and_scale_override(tmp_path):
    text = chain("XYZ", "0 0 0").replace("\n0 0 0 0 0 0 \n", "\n10 20 30 0 0 0 \n")
    p = tmp_path / "t.bvh"
    p.write_text(text)
    take = load_bvh(p, scale=0.5, as_kinect=False)
    np.testing.assert_allclose(take.positions[0, 0], [5.0, 10.0, 15.0])
    np.testing.assert_allclose(take.positions[0, 2], [5.5, 11.0, 15.0])
    assert take.model.joints == ("Root", "Child", "Child_End") and take.model.parents == (-1, 0, 1)


def test_unit_detection_gives_the_same_metres_for_cm_and_m(data_dir, tmp_path):
    text = (data_dir / "bvh" / "mixamo_rig_freebvh.bvh").read_text()
    clip = parse_bvh(text, "m")
    # rewrite the file in metres: OFFSETs and position channels / 100
    lines, out, motion = text.splitlines(), [], False
    pos_cols = []
    col = 0
    for ch in clip.channels:
        pos_cols += [col + k for k, c in enumerate(ch) if c.endswith("position")]
        col += len(ch)
    for line in lines:
        s = line.split()
        if s and s[0] == "OFFSET":
            out.append("OFFSET " + " ".join(repr(float(v) / 100) for v in s[1:]))
        elif motion and len(s) == col:
            vals = [float(v) for v in s]
            out.append(" ".join(repr(v / 100 if i in pos_cols else v) for i, v in enumerate(vals)))
        else:
            out.append(line)
        motion = motion or line.startswith("Frame Time")
    (tmp_path / "m.bvh").write_text("\n".join(out) + "\n")
    a = load_bvh(data_dir / "bvh" / "mixamo_rig_freebvh.bvh")
    b = load_bvh(tmp_path / "m.bvh")
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-9)


def test_detect_unit():
    assert detect_unit(175.0) == (0.01, "cm")
    assert detect_unit(1.8) == (1.0, "m")
    assert detect_unit(68.0) == (0.0254, "inch")
    assert detect_unit(1750.0) == (0.001, "mm")
    per, name = detect_unit(7.0)  # no standard unit makes 7 units a person: normalised to 1.7 m
    assert per * 7.0 == pytest.approx(1.7) and name.startswith("normalised")


def test_up_rotation_is_a_proper_rotation():
    for up in ([0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, -1, 0], [0, 1, 0]):
        r = up_rotation(np.array(up, float))
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(r @ np.array(up, float), [0, 1, 0], atol=1e-12)


QUADRUPED = """HIERARCHY
ROOT Pelvis_bone
{
  OFFSET 0 50 0
  CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation
  JOINT Tail1
  { OFFSET 0 5 -20
    CHANNELS 3 Yrotation Xrotation Zrotation
    End Site
    { OFFSET 0 0 -30 } }
  JOINT Back
  { OFFSET 0 5 40
    CHANNELS 3 Yrotation Xrotation Zrotation
    JOINT Skull
    { OFFSET 0 20 30
      CHANNELS 3 Yrotation Xrotation Zrotation
      End Site
      { OFFSET 0 0 20 } }
    JOINT FrontPaw
    { OFFSET 10 -50 0
      CHANNELS 3 Yrotation Xrotation Zrotation
      End Site
      { OFFSET 0 -5 0 } } }
}
MOTION
Frames: 3
Frame Time: 0.1
0 50 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0
0 50 10 10 0 0 20 0 0 0 0 0 0 0 0 30 0 0
0 50 20 20 0 0 40 0 0 0 0 0 0 0 0 60 0 0
"""


def test_an_animal_keeps_its_own_bones(tmp_path):
    p = tmp_path / "dog.bvh"
    p.write_text(QUADRUPED)
    take = load_bvh(p)
    assert take.model.name == "bvh:dog"
    assert take.model.joints == ("Pelvis_bone", "Tail1", "Tail1_End", "Back", "Skull", "Skull_End",
                                 "FrontPaw", "FrontPaw_End")
    assert len(take.model.bones) == 7
    # the paw swings forward by 30° then 60° about X at the paw joint: its end moves, the skull does not
    paw = take.positions[:, take.model.joints.index("FrontPaw_End")]
    assert np.linalg.norm(paw[2] - paw[0]) > 0.01
    kinetre.subset_mask(take.model, ["Skull", "FrontPaw"])  # subsets name the file's own joints


def test_kinect_map_can_be_turned_off(data_dir):
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh", as_kinect=False)
    assert take.model.name == "bvh:cmu_12_01_walk" and len(take.model.joints) == 38


def _bad(tmp_path, text, name="bad.bvh"):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(BadMotionError) as info:
        load_bvh(p)
    msg = str(info.value)
    assert str(p) in msg
    return msg


def test_missing_motion_section(tmp_path):
    text = chain("XYZ", "0 0 0").split("MOTION")[0]
    assert "no MOTION section" in _bad(tmp_path, text)


def test_wrong_channel_count_in_a_row(tmp_path):
    text = chain("XYZ", "0 0 0 5")  # 7 values, 6 channels
    msg = _bad(tmp_path, text)
    assert "line 19: expected 6 channel values" in msg and "got 7" in msg


def test_channels_line_lists_too_few_names(tmp_path):
    text = chain("XYZ", "0 0 0").replace("Yrotation Zrotation\n", "Yrotation\n")  # 6 declared, 5 named
    assert "line 6: CHANNELS 6 lists 5 channel(s), then 'JOINT'" in _bad(tmp_path, text)
    text = chain("XYZ", "0 0 0").replace("CHANNELS 6 Xposition", "CHANNELS 7 Xposition")
    assert "line 5: channel count must be 0..6, got 7" in _bad(tmp_path, text, "seven.bvh")


def test_truncated_file(tmp_path):
    text = chain("XYZ", "0 0 0").replace("Frames: 1", "Frames: 3")
    assert "truncated: Frames: says 3 but only 1 rows follow" in _bad(tmp_path, text)
    cut = chain("XYZ", "1 2 3").rstrip()[:-2]  # the last row cut mid-way
    assert "line 19: expected 6 channel values (the hierarchy's CHANNELS), got 5" in _bad(tmp_path, cut, "cut.bvh")
    full = chain("XYZ", "0 0 0")
    half = full[:full.index("End Site")]  # cut inside the hierarchy
    assert "line 10: joint 'Child' is not closed with '}'" in _bad(tmp_path, half, "half.bvh")


def test_corrupt_files(tmp_path):
    assert "not a BVH file" in _bad(tmp_path, "PK\x03\x04 binary junk", "zip.bvh")
    assert "line 19: 'abc' is not a number" in _bad(tmp_path, chain("XYZ", "0 0 abc"), "nan.bvh")
    unbalanced = chain("XYZ", "0 0 0").replace("  }\n}\nMOTION", "  }\nMOTION")
    assert "not closed" in _bad(tmp_path, unbalanced, "brace.bvh")
    assert "Frame Time: must be a positive number" in _bad(
        tmp_path, chain("XYZ", "0 0 0").replace("Frame Time: 0.04", "Frame Time: 0"), "ft.bvh")
    assert "then 'Wrotation' (expected Xposition .. Zrotation)" in _bad(
        tmp_path, chain("XYZ", "0 0 0").replace("Xrotation", "Wrotation"), "ch.bvh")
    assert "no such file" in str(pytest.raises(BadMotionError, load_bvh, tmp_path / "none.bvh").value)


def test_bvh_export_reads_back_to_the_same_positions(takes, tmp_path):
    from kinetre.export.bvh import write_bvh
    take = takes["mocapbank_test.bvh"].slice(0, 40)
    write_bvh(tmp_path / "out.bvh", take.frames(), take.fps)
    back = load_bvh(tmp_path / "out.bvh")
    assert back.model == kinetre.KINECT20 and len(back) == len(take)
    assert back.fps == pytest.approx(take.fps, rel=1e-4)
    err = np.abs(back.positions - take.positions).max()
    assert err < 1e-5, f"round trip moved a joint by {err} m"


def test_long_clips_are_solved_in_chunks_with_the_same_result(data_dir, monkeypatch):
    import kinetre.motion.bvh as bvh
    whole = load_bvh(data_dir / "bvh" / "cmu_01_01_hops.bvh")
    monkeypatch.setattr(bvh, "_CHUNK", 100)  # 2752 frames -> 28 chunks, the last one partial
    chunked = load_bvh(data_dir / "bvh" / "cmu_01_01_hops.bvh")
    assert np.array_equal(whole.positions, chunked.positions)
