"""The three exports of one real take: spot.obj (UV-mapped) possessed by the CMU walk (Kinect-20), solved
with Kinetre's own graph, rig and solver, then written as GLB, BVH and MP4 and checked from the files."""
from __future__ import annotations

import dataclasses
import json
import subprocess

import numpy as np
import pytest
from export.bvh_reader import read_bvh_positions
from export.gltf_player import GltfPlayer
from export.takes import placed, validate_gltf
from PIL import Image

import kinetre
from kinetre.export.bvh import write_bvh
from kinetre.export.gltf import write_gltf
from kinetre.export.video import write_video
from kinetre.motion.bvh import load_bvh

FPS = 24.0


@pytest.fixture(scope="module")
def spot_take(data_dir):
    """(mesh, graph, poses, skeleton frames): 24 frames of the CMU walk placed on the cow."""
    mesh = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    graph = kinetre.build_graph(mesh, nodes=128, seed=0)
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = placed([take.frame(i) for i in range(0, 24 * 5, 5)], mesh)       # 24 fps from 120 fps
    rig = kinetre.attach(graph, frames[0])
    assert rig.constraint_count > 0
    poses = [rig.solve(f) for f in frames]
    return mesh, graph, poses, frames


def test_spot_glb_is_valid_and_matches_kinetre_skinning(tmp_path, spot_take):
    mesh, graph, poses, _ = spot_take
    out = tmp_path / "spot.glb"
    write_gltf(out, mesh, graph, poses, FPS, name="spot")
    report = validate_gltf(out)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
    assert report["info"]["animationCount"] == 1 and report["info"]["maxInfluences"] == 4

    player = GltfPlayer(out)
    uv = player.accessor(player.primitive.attributes.TEXCOORD_0)
    np.testing.assert_allclose(uv[:, 0], mesh.uvs[:, 0], atol=1e-6)      # UVs kept
    errors, motion = [], []
    for k, pose in enumerate(poses):
        ours = kinetre.skin(mesh, graph, pose)
        errors.append(np.linalg.norm(player.skin(k / FPS) - ours, axis=1) / mesh.diagonal)
        motion.append(np.linalg.norm(ours - mesh.vertices, axis=1).max() / mesh.diagonal)
    errors = np.array(errors)
    print(f"\nspot.glb fidelity: median {np.median(errors):.5%}, max {errors.max():.5%} of the bbox diagonal "
          f"({errors.shape[0]} frames x {errors.shape[1]} vertices); the take moves vertices by up to "
          f"{max(motion):.1%}")
    assert errors.max(axis=1).max() < 0.01          # every frame within 1 % of the diagonal
    assert max(motion) > 0.05                        # ...of a take that really deforms the mesh


def test_spot_bvh_round_trip(tmp_path, spot_take):
    *_, frames = spot_take
    write_bvh(tmp_path / "spot.bvh", frames, FPS)
    read, frame_time = read_bvh_positions(tmp_path / "spot.bvh")
    assert frame_time == pytest.approx(1 / FPS)
    for j, name in enumerate(kinetre.KINECT20.joints):
        truth = np.stack([f.positions[j] for f in frames])
        assert np.abs(read[name] - truth).max() < 1e-4, name


@pytest.mark.slow
def test_spot_video(tmp_path, spot_take):
    mesh, graph, poses, frames = spot_take
    out = tmp_path / "spot.mp4"
    write_video(out, mesh, graph, poses, FPS, skeletons=[[f] for f in frames])
    info = json.loads(subprocess.run(
        ["ffprobe", "-v", "error", "-count_frames", "-show_entries",
         "stream=codec_name,width,height,r_frame_rate,nb_read_frames", "-of", "json", str(out)],
        capture_output=True, text=True, check=True).stdout)["streams"][0]
    assert (info["codec_name"], info["width"], info["height"]) == ("h264", 640, 480)
    assert info["r_frame_rate"] == "24/1" and int(info["nb_read_frames"]) == len(poses)
    raw = subprocess.run(["ffmpeg", "-v", "error", "-i", str(out), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
                         capture_output=True, check=True).stdout
    video = np.frombuffer(raw, np.uint8).reshape(-1, 480, 640, 3).astype(np.int16)
    assert (np.abs(np.diff(video, axis=0)).mean(axis=(1, 2, 3)) > 0.05).all()
    Image.fromarray(video[12].astype(np.uint8)).save(tmp_path / "spot_12.png")
    # the cow (grey: its OBJ names no texture, trimesh substitutes a plain grey 100) covers part of the frame,
    # darker than the sky and the lit ground
    assert (video[12].max(axis=2) < 110).mean() > 0.02


@pytest.mark.slow
def test_scaled_take_keeps_fidelity(tmp_path, spot_take):
    """The same take in millimetres: the error scales with the mesh (no absolute epsilon inside)."""
    mesh, graph, poses, _ = spot_take
    k = 1000.0
    big_mesh = dataclasses.replace(mesh, vertices=mesh.vertices * k)
    big_graph = dataclasses.replace(graph, nodes=graph.nodes * k)
    big_poses = [dataclasses.replace(p, translations=p.translations * k) for p in poses[::6]]
    write_gltf(tmp_path / "big.gltf", big_mesh, big_graph, big_poses, FPS / 6)
    player = GltfPlayer(tmp_path / "big.gltf")
    for i, pose in enumerate(big_poses):
        err = np.linalg.norm(player.skin(i * 6 / FPS) - kinetre.skin(big_mesh, big_graph, pose), axis=1)
        assert err.max() / big_mesh.diagonal < 0.01
