"""Exports of retargeted takes: the GLB passes the Khronos validator and plays the same in an independent
glTF reader (tests/export/gltf_player.py) and in three.js (the studio's SkinnedMesh) as in our numpy LBS;
BVH re-reads to the same joint positions; the `kinetre avatar` command end to end."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from export.gltf_player import GltfPlayer
from export.takes import validate_gltf
from kinetre.avatar.export import write_avatar_bvh, write_avatar_gltf
from kinetre.avatar.retarget import retarget
from kinetre.avatar.skin import bind_bounds, skin_avatar
from kinetre.cli import main
from kinetre.motion.bvh import forward_kinematics, parse_bvh

from avatar.conftest import HUMANOIDS

THREE = Path(__file__).resolve().parent / "node" / "skin_three.mjs"
TIMES = (0, 17, 41)          # frames compared (a T-pose, mid-stride, another stride)


@pytest.fixture(scope="module")
def exported(tmp_path_factory, rigged, walk):
    """name -> (path, avatar, motion) for each humanoid, the walk written as .glb."""
    out = {}
    for name in HUMANOIDS:
        avatar, _, plan = rigged[name]
        motion = retarget(plan, walk.positions, walk.tracked)
        path = tmp_path_factory.mktemp("avatar") / f"{name}_walk.glb"
        write_avatar_gltf(path, avatar, motion, walk.fps)
        out[name] = (path, avatar, motion)
    return out


def diagonal(avatar) -> float:
    lo, hi = bind_bounds(avatar)
    return float(np.linalg.norm(hi - lo))


@pytest.mark.slow
@pytest.mark.parametrize("name", HUMANOIDS)
def test_the_glb_is_validator_clean_and_animates_the_avatars_own_joints(exported, name):
    path, avatar, motion = exported[name]
    report = validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    assert report["info"]["hasSkins"] and report["info"]["animationCount"] == 1
    player = GltfPlayer(path)
    targets = {node for node, *_ in player.tracks}
    assert targets == {int(n) for n in avatar.joints}        # its own joints, nothing added
    assert len(player.doc.nodes) == len(avatar.doc.nodes)


@pytest.mark.parametrize("name", HUMANOIDS)
def test_an_independent_reader_and_three_js_skin_it_like_our_lbs(exported, walk, name):
    path, avatar, motion = exported[name]
    diag = diagonal(avatar)
    ours = skin_avatar(avatar, motion.world[list(TIMES)])
    players = [GltfPlayer(path, mesh_node=p.node, primitive=p.index) for p in avatar.primitives]
    three = json.loads(subprocess.run(["node", str(THREE), str(path), *(str(t / walk.fps) for t in TIMES)],
                                      capture_output=True, text=True, timeout=300, check=True).stdout)
    for f, t in enumerate(TIMES):
        page = {(m["mesh"], m["primitive"]): np.array(m["positions"]).reshape(-1, 3) for m in three["frames"][f]}
        assert len(page) == len(avatar.primitives)
        for k, prim in enumerate(avatar.primitives):
            theirs = players[k].skin(t / walk.fps)
            assert np.linalg.norm(theirs - ours[f][k], axis=1).max() <= 1e-3 * diag
            err = np.linalg.norm(page[(prim.mesh, prim.index)] - ours[f][k], axis=1).max()
            assert err <= 1e-3 * diag, (t, k, err / diag)
    # not a trivial agreement: the walk moves vertices by a good fraction of the body
    far = max(np.linalg.norm(ours[2][k] - ours[0][k], axis=1).max() for k in range(len(avatar.primitives)))
    assert far > 0.1 * diag


def test_bvh_export_rebuilds_the_avatars_joint_positions(tmp_path, rigged, walk):
    avatar, _, plan = rigged["robot_quaternius"]
    motion = retarget(plan, walk.positions, walk.tracked)
    path = tmp_path / "robot.bvh"
    write_avatar_bvh(path, avatar, plan, motion, walk.fps)
    clip = parse_bvh(path.read_text(), str(path))
    assert len(clip.motion) == len(walk)
    assert all(len(c) == 3 for c, p in zip(clip.channels, clip.parents) if p >= 0 and c)   # rotations only
    fk = forward_kinematics(clip)
    index = [clip.names.index(n) for n in avatar.joint_names]
    np.testing.assert_allclose(fk[:, index], motion.positions, atol=2e-5 * np.ptp(avatar.bind_positions))


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_writes_an_animated_avatar_and_refuses_a_fox(tmp_path, capsys, data_dir):
    out = tmp_path / "cesium.glb"
    code, text, err = run(capsys, "avatar", data_dir / "avatars" / "CesiumMan.glb", "--motion",
                          data_dir / "bvh" / "mocapbank_test.bvh", "-o", out, "--max-frames", "20")
    assert code == 0, err
    assert "HipCenter<-joint0 (geometry)" in text and out.exists()
    assert len(GltfPlayer(out).tracks[0][3]) == 20
    code, text, err = run(capsys, "avatar", data_dir / "avatars" / "Fox.glb", "--motion",
                          data_dir / "bvh" / "cmu_12_01_walk.bvh", "-o", tmp_path / "fox.glb")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "Fox.glb: not an upright humanoid" in err and "kinetre animate Fox.glb" in err
    code, text, err = run(capsys, "avatar", data_dir / "meshes" / "spot.obj", "--motion",
                          data_dir / "bvh" / "cmu_12_01_walk.bvh", "-o", tmp_path / "x.glb")
    assert code == 2 and "an avatar must be a rigged .glb, .gltf or .vrm file" in err


def test_cli_writes_and_then_uses_a_map_next_to_the_avatar(tmp_path, capsys, data_dir):
    import shutil
    avatar = tmp_path / "figure.glb"
    shutil.copy(data_dir / "avatars" / "RiggedFigure.glb", avatar)
    code, text, err = run(capsys, "avatar", avatar, "--write-map")
    assert code == 0, err
    saved = json.loads((tmp_path / "figure.glb.kinetre-map.json").read_text())
    assert saved["kinect20"]["ElbowLeft"] == "arm_joint_L_2"
    saved["kinect20"]["ShoulderCenter"] = "torso_joint_3"
    (tmp_path / "figure.glb.kinetre-map.json").write_text(json.dumps(saved))
    code, text, err = run(capsys, "avatar", avatar, "--motion", data_dir / "bvh" / "cmu_12_01_walk.bvh",
                          "-o", tmp_path / "walk.bvh", "--max-frames", "5")
    assert code == 0, err
    assert "ShoulderCenter<-torso_joint_3 (file)" in text


@pytest.mark.slow
def test_cli_drives_an_avatar_from_a_recorded_take_into_a_video(tmp_path, capsys, data_dir):
    import cv2
    take = tmp_path / "walk.kinetre.jsonl"
    code, _, err = run(capsys, "record", data_dir / "bvh" / "cmu_12_01_walk.bvh", "-o", take, "--fps", "30")
    assert code == 0, err
    video = tmp_path / "robot.mp4"
    code, text, err = run(capsys, "avatar", data_dir / "avatars" / "robot_quaternius.glb", "--motion", take,
                          "-o", video, "--frames", "60:", "--max-frames", "8", "-q")
    assert code == 0, err
    cap = cv2.VideoCapture(str(video))
    frames = []
    while True:
        ok, image = cap.read()
        if not ok:
            break
        frames.append(image.astype(float))
    cap.release()
    assert len(frames) == 8 and frames[0].shape == (480, 640, 3)
    # the avatar is drawn (orange robot pixels: red well above blue) and it moves between frames
    orange = lambda f: ((f[..., 2] - f[..., 0]) > 80).mean()                       # OpenCV frames are BGR
    assert min(orange(f) for f in frames) > 0.01
    assert np.abs(frames[-1] - frames[0]).mean() > 0.5
