"""Every BVH of the shared data: its Kinect-20 take survives a BVH round trip through our parser, and, driving
spot.obj, exports to a GLB that passes the Khronos validator and that a glTF player skins like Kinetre."""
from __future__ import annotations

import numpy as np
import pytest
from export.gltf_player import GltfPlayer
from export.takes import DATA, placed, validate_gltf

import kinetre
from kinetre.export.bvh import rotation_residuals, write_bvh
from kinetre.export.gltf import write_gltf
from kinetre.motion.bvh import load_bvh

BVHS = sorted((DATA / "bvh").glob("*.bvh"))


def test_the_shared_data_has_bvh_files():
    assert len(BVHS) >= 5


@pytest.mark.parametrize("bvh", BVHS, ids=lambda p: p.stem)
def test_bvh_round_trip_through_our_parser(tmp_path, bvh):
    take = load_bvh(bvh)
    frames = [take.frame(i) for i in range(len(take))]
    write_bvh(tmp_path / "out.bvh", frames, take.fps)
    back = load_bvh(tmp_path / "out.bvh", scale=1.0)
    assert back.model == take.model and len(back) == len(take)
    assert back.fps == pytest.approx(take.fps, rel=1e-6)
    err = np.abs(back.positions - take.positions).max()
    res = rotation_residuals(frames)
    print(f"\n{bvh.name}: {len(take)} frames, round trip max error {err:.2e} m; a rotation-only reader would be "
          f"off by median {np.nanmedian(res) * 1000:.1f} mm, max {np.nanmax(res) * 1000:.1f} mm")
    assert err < 1e-4


@pytest.fixture(scope="module")
def spot():
    mesh = kinetre.load_mesh(DATA / "meshes" / "spot.obj")
    return mesh, kinetre.build_graph(mesh, nodes=128, seed=0)


@pytest.mark.slow
@pytest.mark.parametrize("bvh", BVHS, ids=lambda p: p.stem)
def test_mocap_driven_glb_is_valid_and_faithful(tmp_path, spot, bvh):
    mesh, graph = spot
    take = load_bvh(bvh)
    step = max(1, len(take) // 20)                  # ~20 keys spread over the whole clip
    frames = placed([take.frame(i) for i in range(0, len(take), step)], mesh)
    rig = kinetre.attach(graph, frames[0])
    poses = [rig.solve(f) for f in frames]
    fps = take.fps / step
    out = tmp_path / "take.glb"
    write_gltf(out, mesh, graph, poses, fps, name=bvh.stem)
    report = validate_gltf(out)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]

    player = GltfPlayer(out)
    ours = [kinetre.skin(mesh, graph, p) for p in poses]
    err = np.array([np.linalg.norm(player.skin(k / fps) - v, axis=1) for k, v in enumerate(ours)]) / mesh.diagonal
    write_gltf(tmp_path / "polar.glb", mesh, graph, poses, fps, stretch=False)
    polar = GltfPlayer(tmp_path / "polar.glb")
    perr = np.array([np.linalg.norm(polar.skin(k / fps) - v, axis=1) for k, v in enumerate(ours)]) / mesh.diagonal
    motion = max(np.linalg.norm(v - mesh.vertices, axis=1).max() for v in ours) / mesh.diagonal
    print(f"\n{bvh.name} on spot ({len(poses)} keys, {len(rig.attached_joints[0])} joints attached, vertices "
          f"move up to {motion:.0%} of the diagonal): default export median {np.median(err):.5%} max "
          f"{err.max():.5%}; polar rotations only median {np.median(perr):.5%} max {perr.max():.5%}")
    assert err.max(axis=1).max() < 0.01
    assert motion > 0.05
