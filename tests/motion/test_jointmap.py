"""Joint maps join sources into one skeleton; two people walk the front and back legs of a quadruped."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from export.gltf_player import GltfPlayer
from export.takes import validate_gltf

import kinetre
from kinetre.cli import main
from kinetre.errors import BadMotionError
from kinetre.motion.jointmap import join_takes, parse_joint_map, read_joint_map
from kinetre.motion.take import Take

MAPS = Path(__file__).resolve().parents[2] / "examples" / "maps"


def _walker(z0: float, frames: int = 4) -> Take:
    """A Kinect-20 stick person at z0, stepping +x by 0.1 per frame."""
    pos = np.zeros((frames, 20, 3))
    pos[:, :, 1] = np.linspace(0.0, 1.7, 20)
    pos[:, :, 2] = z0
    pos[:, :, 0] = 0.1 * np.arange(frames)[:, None]
    return Take(kinetre.KINECT20, pos, np.ones((frames, 20), bool), 30.0, f"walker{z0}")


def test_example_maps_join_two_people_into_one_skeleton():
    for name in ("two-people-horse.json", "arms-to-front-legs.json"):
        take = join_takes([_walker(0.0), _walker(0.0)], read_joint_map(MAPS / name))
        assert take.model.name == f"map:{name[:-5]}" and len(take) == 4
    take = join_takes([_walker(0.0), _walker(0.0)], read_joint_map(MAPS / "two-people-horse.json"))
    names = take.model.joints
    assert len(names) == 18 and names[0] == "FrontHips" and names[9] == "BackHips"
    assert take.model.parents[9] == 0                                   # the back hangs from the front hips
    assert take.model.parents[names.index("FrontKneeLeft")] == names.index("FrontHipLeft")
    assert take.model.parents[names.index("FrontHipLeft")] == 0        # HipCenter renamed, still the parent
    np.testing.assert_allclose(take.positions[:, :9, 2], 0.45)         # offsets
    np.testing.assert_allclose(take.positions[:, 9:, 2], -0.45)


def test_one_camera_take_with_two_people_drives_both_halves():
    front, back = _walker(0.0), _walker(2.0)
    crowd = np.stack([back.positions, front.positions], axis=1)        # ids 5 (back) and 3 (front)
    camera = Take(front.model, back.positions, back.tracked, 30.0, "camera", (5, 3), crowd,
                  np.ones((4, 2, 20), bool))
    jmap = read_joint_map(MAPS / "two-people-horse.json")
    joined = join_takes([camera], jmap)
    np.testing.assert_array_equal(joined.positions, join_takes([front, back], jmap).positions)  # id 3 first
    with pytest.raises(BadMotionError, match=r"describes 2 source\(s\) but 1 motion"):
        join_takes([front], jmap)


def test_drop_reparents_yaw_turns_and_lengths_join():
    jmap = parse_joint_map({"sources": [{"drop": ["Spine", "arms"], "yaw": 90}]}, "m.json")
    take = join_takes([_walker(0.0, 6)], jmap)
    assert "Spine" not in take.model.joints and "HandLeft" not in take.model.joints
    assert take.model.parents[take.model.index("ShoulderCenter")] == take.model.index("HipCenter")
    # +x steps turned 90 deg about +Y become -z steps
    np.testing.assert_allclose(np.diff(take.positions[:, 0, 2]), -0.1, atol=1e-12)
    two = join_takes([_walker(0.0, 6), _walker(1.0, 3)],
                     parse_joint_map({"sources": [{"keep": ["legs"]}, {"keep": ["Head"],
                                                                         "rename": {"Head": "Head2"}}]}))
    assert len(two) == 3 and two.model.joints[-1] == "Head2"


@pytest.mark.parametrize("obj, message", [
    ([], "expected an object"),
    ({"sources": [{"kep": ["legs"]}]}, r"unknown key\(s\) kep"),
    ({"sources": [{"offset": [0, 1]}]}, "'offset' must be 3 finite numbers"),
    ({"sources": [{"keep": ["tail"]}]}, "unknown joint subset 'tail'"),
    ({"sources": [{"rename": {"Hed": "X"}}]}, "'Hed' is not a joint"),
    ({"sources": [{}, {}]}, "describes 2 source"),
    ({"sources": [{"parent": {"Head": "HipCenter"}}]}, "already has a parent"),
])
def test_bad_maps_name_the_key(obj, message):
    with pytest.raises(BadMotionError, match=message):
        join_takes([_walker(0.0)], parse_joint_map(obj, "m.json"))


def test_same_names_from_two_sources_are_refused():
    with pytest.raises(BadMotionError, match="'HipLeft' is kept twice"):
        join_takes([_walker(0.0), _walker(0.0)], parse_joint_map({"sources": [{"keep": ["legs"]},
                                                                               {"keep": ["legs"]}]}))


def test_two_bvh_walkers_drive_the_front_and_back_legs_of_spot(data_dir, tmp_path, capsys):
    walk = str(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    out = tmp_path / "spot.glb"
    code = main(["animate", str(data_dir / "meshes" / "spot.obj"), "--motion", walk, "--motion", walk,
                 "--frames", "0:240", "--fps", "15", "--map", str(MAPS / "two-people-horse.json"),
                 "--nodes", "96", "-o", str(out)])
    printed = capsys.readouterr().out
    assert code == 0 and "map:two-people-horse, 18 joints" in printed
    assert validate_gltf(out)["issues"]["numErrors"] == 0
    player = GltfPlayer(out)
    frames = np.stack([player.skin(t) for t in player.tracks[0][3]])
    rest = frames[0]
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    lower = rest[:, 1] < lo[1] + (hi[1] - lo[1]) / 3
    # the front and the back legs (the lower third, split along Spot's long axis z) both move relative to
    # the body's own travel
    z = rest[:, 2]
    body = frames - frames[:, ~lower].mean(axis=1, keepdims=True)
    moved = np.linalg.norm(body - body[0], axis=2).max(axis=0)
    diagonal = float(np.linalg.norm(hi - lo))
    middle = np.median(z[lower])
    for end in (z < middle, z >= middle):
        assert moved[lower & end].max() > 0.05 * diagonal


def test_several_motions_need_a_map(data_dir, tmp_path, capsys):
    walk = str(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    assert main(["animate", str(data_dir / "meshes" / "spot.obj"), "--motion", walk, "--motion", walk,
                 "-o", str(tmp_path / "x.glb")]) == 2
    assert "--map" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"sources": [{"keep": ["legs"]}]}))
    assert main(["animate", str(data_dir / "meshes" / "spot.obj"), "--motion", walk, "--motion", walk,
                 "--map", str(bad), "-o", str(tmp_path / "x.glb")]) == 2
    assert "describes 1 source(s) but 2 motion(s)" in capsys.readouterr().err
