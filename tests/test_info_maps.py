"""`kinetre info SOURCE` prints the Kinect-20 map of any skeleton: BVH, glTF animation, avatar, recorded take;
which source joint plays which joint (and how it was found), what is derived, what is untracked and why."""
from __future__ import annotations

import re

import numpy as np
import pytest

from kinetre.cli import main
from kinetre.motion.bvh import parse_bvh

from skeleton.test_humanoid_map import NECKLESS, bvh_text


def info(capsys, path) -> str:
    code = main(["info", str(path)])
    out, err = capsys.readouterr()
    assert code == 0, err
    return out


def map_lines(out: str, header: str) -> dict:
    """Kinect joint -> (source, how) of the map printed under the line starting with `header`."""
    lines = out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().startswith(header))
    found = {}
    for line in lines[start + 1:]:
        m = re.match(r"^    (\w+) <- (.+) \((\w+)\)$", line)
        if not m:
            if not line.startswith("     "):
                break
            continue
        found[m.group(1)] = (m.group(2), m.group(3))
    return found


def test_a_bvh(capsys, data_dir):
    out = info(capsys, data_dir / "bvh" / "mocapbank_test.bvh")
    assert "Kinect-20 map: a humanoid, 20 of 20 joints tracked (0 derived)" in out
    m = map_lines(out, "Kinect-20 map")
    assert m["ShoulderLeft"] == ("LeftShoulder", "name") and m["HandLeft"] == ("LeftWrist_End", "name")
    assert len(m) == 20


def test_a_bvh_without_neck_and_elbows_says_what_is_derived_and_untracked(capsys, data_dir, tmp_path):
    clip = parse_bvh((data_dir / "bvh" / "cmu_12_01_walk.bvh").read_text())
    keep = [clip.names.index(n) for n in NECKLESS if n not in ("LeftForeArm", "RightForeArm")]
    path = tmp_path / "chibi.bvh"
    path.write_text(bvh_text(clip, keep, {}))
    out = info(capsys, path)
    assert "Kinect-20 map: a humanoid, 18 of 20 joints tracked (3 derived)" in out
    m = map_lines(out, "Kinect-20 map")
    assert m["ShoulderCenter"] == ("Spine", "topology") and m["WristLeft"] == ("LeftHand", "name")
    assert "    Spine <- 0.75 Hips + 0.25 Spine (derived)" in out
    assert "    HandLeft <- 1.125 LeftHand - 0.125 LeftArm (derived)" in out
    assert "    not mapped (untracked): ElbowLeft, ElbowRight" in out
    assert "      ElbowLeft: no joint between LeftArm and LeftHand" in out


@pytest.mark.slow
def test_a_glb_avatar_and_its_animations(capsys, data_dir):
    out = info(capsys, str(data_dir / "avatars" / "robot_quaternius.glb") + "#Robot_Dance")
    assert "avatar: 43 skin joints; bone map: drivable by kinetre avatar, 18 of 20 joints mapped" in out
    avatar, motion = map_lines(out, "avatar:"), map_lines(out, "Kinect-20 map")
    assert avatar["HipCenter"] == ("Body", "topology") and avatar["ShoulderLeft"] == ("UpperArm.L", "name")
    assert {k: v[0] for k, v in motion.items()} == {k: v[0] for k, v in avatar.items()}   # one skeleton, one map
    assert "FootLeft <- 1.25 Foot.L - 0.25 LowerLeg.L (derived)" in out


def test_a_fox_is_no_humanoid_either_way(capsys, data_dir):
    out = info(capsys, data_dir / "avatars" / "Fox.glb")
    assert "bone map: not an upright humanoid (its spine (b_Hip_01 -> b_Neck_04) is 79 degrees from vertical)" in out
    assert re.search(r"Kinect-20 map: none \(its legs are \d+ degrees off the line of its spine\): --motion Fox.glb "
                     r"drives a mesh by its own bones", out)


def test_recorded_takes(capsys, data_dir, tmp_path):
    kinect = tmp_path / "walk.kinetre.jsonl"
    assert main(["record", str(data_dir / "bvh" / "cmu_12_01_walk.bvh"), "-o", str(kinect), "--fps", "30"]) == 0
    capsys.readouterr()
    assert "Kinect-20 map: the take's own joints (Kinect-20)" in info(capsys, kinect)
    # a take of a skeleton kept with its own bones: mapped from its first frame
    own = tmp_path / "own.kinetre.jsonl"
    from kinetre.motion.bvh import load_bvh
    from kinetre.motion.stream import write_stream
    take = load_bvh(data_dir / "bvh" / "pybvh_test1.bvh", as_kinect=False)
    write_stream(own, take)
    out = info(capsys, own)
    m = map_lines(out, "Kinect-20 map")
    assert m["HipCenter"] == ("Hips", "name") and m["KneeRight"] == ("RightLeg", "name") and len(m) == 20
    assert np.isfinite(take.positions[0]).all()
