"""Blender as a client: Debian's Blender imports each kind of Kinetre export with its own importers, its evaluated
deformation matches the file's skinning (an independent player) within 0.01 % of the height, and its own glTF
exporter at 30 fps keeps the take's frame count. One Blender process probes every file (tests/export/blender_probe.py)."""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pygltflib as gl
import pytest

from export.gltf_player import GltfPlayer
from face.fixtures_face import pan_video
from kinetre.cli import main
from kinetre.motion.bvh import forward_kinematics, parse_bvh

pytestmark = pytest.mark.skipif(shutil.which("blender") is None, reason="Blender is not installed (make setup does)")
PROBE = Path(__file__).resolve().parent / "blender_probe.py"
FRAMES = 6
SAMPLED = (0, 3, 5)


@pytest.fixture(scope="module")
def probed(tmp_path_factory, data_dir):
    tmp = tmp_path_factory.mktemp("blender")
    walk = data_dir / "bvh" / "cmu_12_01_walk.bvh"
    common = ["--max-frames", FRAMES, "--fps", 30, "-q"]
    files = {"possessed": tmp / "spot.glb", "avatar": tmp / "cesium.glb", "face": tmp / "face.glb"}
    runs = [["animate", data_dir / "meshes" / "spot.obj", "--motion", walk, "-o", files["possessed"], "--nodes", 48,
             *common],
            ["avatar", data_dir / "avatars" / "CesiumMan.glb", "--motion", walk, "-o", files["avatar"], *common],
            ["avatar", data_dir / "avatars" / "CesiumMan.glb", "--motion", walk, "-o", tmp / "cesium.bvh", *common]]
    for argv in runs:
        assert main([str(a) for a in argv]) == 0
    pan_video(data_dir / "images" / "face" / "face_frontal_portrait.jpg", tmp / "pan.mp4")
    assert main(["face", str(tmp / "pan.mp4"), "-o", str(files["face"]), "--max-frames", str(FRAMES),
                 "--morph", "eyes=0.5"]) == 0
    job = {"fps": 30, "gltf": [{"path": str(p), "frames": list(SAMPLED), "export": str(tmp / f"{k}_blender.glb")}
                               for k, p in files.items()],
           "bvh": [{"path": str(tmp / "cesium.bvh"), "frames": list(SAMPLED)}]}
    (tmp / "job.json").write_text(json.dumps(job))
    subprocess.run(["blender", "-b", "--factory-startup", "--python", str(PROBE), "--", str(tmp / "job.json"),
                    str(tmp / "out.json")], capture_output=True, timeout=600, check=True)
    out = json.loads((tmp / "out.json").read_text())
    return {k: (files[k], tmp / f"{k}_blender.glb", res) for k, res in zip(files, out["gltf"])}, \
        (tmp / "cesium.bvh", out["bvh"][0])


@pytest.mark.parametrize("kind", ["possessed", "avatar"])
def test_blender_skins_the_glb_like_the_file_says(probed, kind):
    path, _, res = probed[0][kind]
    player = GltfPlayer(path)
    height = np.ptp(player.positions[:, 1])
    (blender,) = res["meshes"].values()
    moved = 0.0
    for k, frame in enumerate(SAMPLED):
        theirs = np.array(blender["frames"][k])
        ours = player.skin(frame / 30)
        assert np.abs(theirs - ours).max() < 1e-4 * height, (frame, np.abs(theirs - ours).max() / height)
        moved = max(moved, np.abs(ours - np.array(blender["frames"][0])).max())
    assert moved > 0.01 * height          # the take really moves the mesh


def test_blender_plays_the_face_morphs(probed):
    path, _, res = probed[0]["face"]
    doc = gl.GLTF2.load(str(path))
    player = GltfPlayer.__new__(GltfPlayer)
    player.doc, player.blob = doc, doc.binary_blob()
    prim = doc.meshes[0].primitives[0]
    base = player.accessor(prim.attributes.POSITION).astype(float)
    targets = np.stack([player.accessor(t["POSITION"]) for t in prim.targets]).astype(float)
    anim = doc.animations[0]
    keys = player.accessor(anim.samplers[0].output).reshape(-1, len(targets))
    height = np.ptp(base[:, 1])
    (blender,) = res["meshes"].values()
    for k, frame in enumerate(SAMPLED):
        played = base + np.einsum("t,tvc->vc", keys[frame], targets)
        err = np.abs(np.array(blender["frames"][k]) - played).max()
        assert err < 1e-4 * height, (frame, err / height)


@pytest.mark.parametrize("kind", ["possessed", "avatar", "face"])
def test_blenders_exporter_at_30_fps_keeps_the_frame_count(probed, kind):
    _, exported, _ = probed[0][kind]
    doc = gl.GLTF2.load(str(exported))
    times = doc.accessors[doc.animations[0].samplers[0].input]
    assert times.count == FRAMES and times.max[0] == pytest.approx((FRAMES - 1) / 30, abs=1e-4)


def test_blender_reads_the_bvh_to_our_joint_positions(probed):
    path, res = probed[1]
    clip = parse_bvh(path.read_text(), str(path))
    fk = forward_kinematics(clip)
    height = np.ptp(fk[0][:, 1])
    assert res["fps"] == 30
    for name, positions in res["joints"].items():
        ours = fk[list(SAMPLED), clip.names.index(name)]
        assert np.abs(np.array(positions) - ours).max() < 1e-4 * height, name
