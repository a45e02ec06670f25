"""Any rig's animation drives any mesh: Fox.glb#Walk walks the shared spot and armadillo.

The written GLB is skinned by the tests' independent player (tests/export/gltf_player.py) and checked with
the Khronos validator; the bound on per-frame motion comes from the placed source itself, so a jump is a
mesh vertex moving much faster than any joint that drives it (measured: spot 0.07, armadillo 0.20 of the
diagonal at most per frame, against 0.11 for the fastest joint).
"""
from __future__ import annotations

import numpy as np
import pytest
from export.gltf_player import GltfPlayer
from export.takes import validate_gltf

import kinetre
from kinetre.cli import main
from kinetre.motion.align import fit_shapes
from kinetre.motion.source import load_take, resample


@pytest.mark.slow
@pytest.mark.parametrize("mesh_name", ["spot.obj", "armadillo.obj"])
def test_fox_walk_drives_a_mesh(data_dir, tmp_path, capsys, mesh_name):
    mesh_path, motion = data_dir / "meshes" / mesh_name, f"{data_dir / 'avatars' / 'Fox.glb'}#Walk"
    out = tmp_path / "out.glb"
    assert main(["animate", str(mesh_path), "--motion", motion, "-o", str(out), "--nodes", "96", "-q"]) == 0
    report = validate_gltf(out)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"][:5]

    player = GltfPlayer(out)
    times = player.tracks[0][3]
    frames = np.stack([player.skin(t) for t in times])
    rest = frames[0]
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    diagonal = float(np.linalg.norm(hi - lo))
    lower = rest[:, 1] < lo[1] + (hi[1] - lo[1]) / 3
    motion_lower = np.linalg.norm(frames[:, lower] - rest[lower], axis=2).max()
    assert motion_lower >= 0.05 * diagonal, f"the legs barely move: {motion_lower / diagonal:.3f} of the diagonal"

    # the fastest joint of the placed source, in the mesh's units, per frame
    mesh = kinetre.load_mesh(mesh_path)
    take = resample(load_take(motion), 30.0)
    placement = fit_shapes(take, mesh).placement
    joints = placement.take(take).positions * placement.output_scale
    joint_step = np.linalg.norm(np.diff(joints, axis=0), axis=2).max()
    vertex_step = np.linalg.norm(np.diff(frames, axis=0), axis=2).max()
    assert len(times) == len(take)
    # lever arms (an armadillo's arms round a fox's spine) may outrun the fastest joint a little; a jump (a
    # flip, a lost solve) moves the mesh by a good part of its size in one frame
    assert vertex_step <= 2.5 * joint_step, (vertex_step, joint_step)
    assert vertex_step <= 0.25 * diagonal


def test_unknown_animation_lists_the_available_ones(data_dir, tmp_path, capsys):
    code = main(["animate", str(data_dir / "meshes" / "spot.obj"), "--motion",
                 f"{data_dir / 'avatars' / 'Fox.glb'}#Trot", "-o", str(tmp_path / "x.glb")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "no animation named 'Trot'" in err and "'Survey'" in err and "'Walk'" in err and "'Run'" in err
    assert not (tmp_path / "x.glb").exists()


def test_info_lists_the_animations(data_dir, capsys):
    assert main(["info", str(data_dir / "avatars" / "Fox.glb")]) == 0
    out = capsys.readouterr().out
    assert "#0 Survey" in out and "#1 Walk" in out and "#2 Run" in out and "26 joints" in out


def test_a_poor_match_says_so(data_dir, tmp_path, capsys):
    """The fox is twice as long for its height as the armadillo: the command says so and what to try."""
    assert main(["animate", str(data_dir / "meshes" / "armadillo.obj"), "--motion",
                 f"{data_dir / 'avatars' / 'Fox.glb'}#Walk", "-o", str(tmp_path / "a.bvh")]) == 0
    err = capsys.readouterr().err
    assert "poor match" in err and "--fit height" in err


@pytest.mark.slow
def test_hints_turn_and_size_the_source(data_dir):
    mesh = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    take = load_take(f"{data_dir / 'avatars' / 'Fox.glb'}#Walk")
    auto = fit_shapes(take, mesh)
    flipped = fit_shapes(take, mesh, flip=True)
    assert abs((flipped.turn - auto.turn) % 360.0 - 180.0) < 1e-6
    turned = fit_shapes(take, mesh, yaw=90.0)
    assert abs((turned.turn - auto.turn) % 360.0 - 90.0) < 1e-6
    by_height = fit_shapes(take, mesh, fit="height").placement.skeleton_scale
    by_length = fit_shapes(take, mesh, fit="length").placement.skeleton_scale
    assert by_height == pytest.approx(auto.ratios[0]) and by_length == pytest.approx(auto.ratios[1])


def test_an_animal_bvh_is_fitted_the_same_way(data_dir, tmp_path):
    """The fox written as BVH (its own hierarchy, no Kinect-20 names) reads back as a generic skeleton
    and lands in Spot as the glTF did: same facing, same share of bones inside."""
    from kinetre.export.bvh import write_bvh
    fox = load_take(f"{data_dir / 'avatars' / 'Fox.glb'}#Walk")
    write_bvh(tmp_path / "fox.bvh", fox.frames(), fox.fps)
    animal = load_take(tmp_path / "fox.bvh")
    assert animal.model.name == "bvh:fox" and set(fox.model.joints) <= set(animal.model.joints)  # + End Sites
    mesh = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    a, b = fit_shapes(fox, mesh), fit_shapes(animal, mesh)
    assert abs((a.turn - b.turn + 180.0) % 360.0 - 180.0) < 5.0
    assert abs(a.inside - b.inside) < 0.15 and b.inside > 0.6
