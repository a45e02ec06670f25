"""One command from RGB-D frames to an animated glTF: `kinetre animate FRAMES_DIR|FRAMES.zip --motion ...`.

The Redwood living-room frames hold a chair by a wall; what the plane segmentation keeps of this real scene
is reported: when the piece is a flat sheet (a wall) the command says so and animates it as it is.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest
import trimesh
from export.gltf_player import GltfPlayer
from export.takes import validate_gltf

from kinetre.cli import main
from kinetre.mesh.load import load_mesh
from kinetre.scan.subject import FLAT, principal_spread, shape_notes

pytestmark = pytest.mark.slow  # `make check` leaves these out: see docs/testing.md

pytest.importorskip("open3d")


@pytest.mark.parametrize("as_zip", [False, True], ids=["folder", "zip"])
def test_frames_to_animated_glb_in_one_command(data_dir, tmp_path, capsys, as_zip):
    frames = data_dir / "rgbd" / "redwood_livingroom"
    if as_zip:
        frames = shutil.make_archive(str(tmp_path / "redwood"), "zip", frames.parent, frames.name)
    out = tmp_path / "scan_walk.glb"
    code = main(["animate", str(frames), "--motion", str(data_dir / "bvh" / "cmu_12_01_walk.bvh"),
                 "--max-frames", "6", "--fps", "15", "--nodes", "64", "-o", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "scanned" in captured.out and "5 frames used" in captured.out
    assert validate_gltf(out)["issues"]["numErrors"] == 0

    player = GltfPlayer(out)
    poses = np.stack([player.skin(t) for t in player.tracks[0][3]])
    assert len(poses) == 6 and np.isfinite(poses).all()
    rest = poses[0]
    diagonal = float(np.linalg.norm(np.ptp(rest, axis=0)))
    assert np.linalg.norm(poses - rest, axis=2).max() > 0.02 * diagonal  # it is animated
    assert 0.5 < np.ptp(rest, axis=0).max() < 3.0  # a room-scale piece in metres, not a speck or the house
    # the command says when the scan kept a flat sheet rather than an object, and only then
    spread = principal_spread(rest)
    assert ("flat sheet" in captured.err) == bool(spread[2] / spread[0] < FLAT)


def test_frames_that_are_not_rgbd_are_named(tmp_path, data_dir, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["animate", str(empty), "--motion", str(data_dir / "bvh" / "cmu_12_01_walk.bvh"),
                 "-o", str(tmp_path / "x.glb")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("kinetre: error:") and err.count("\n") == 1
    assert not (tmp_path / "x.glb").exists()


def test_scan_options_need_frames(data_dir, tmp_path, capsys):
    assert main(["animate", str(data_dir / "meshes" / "spot.obj"), "--motion",
                 str(data_dir / "bvh" / "cmu_12_01_walk.bvh"), "--segment", "change", "-o",
                 str(tmp_path / "x.glb")]) == 2
    assert "apply when the input is RGB-D frames" in capsys.readouterr().err



def _mesh(tm, tmp_path):
    path = tmp_path / f"{id(tm)}.ply"
    tm.export(path)
    return load_mesh(path)


def test_a_flat_sheet_is_told_apart_from_an_object(data_dir, tmp_path):
    wall = _mesh(trimesh.creation.box(extents=(1.3, 1.2, 0.02)), tmp_path)
    notes = shape_notes(wall, "wall")
    assert len(notes) == 1 and "flat sheet" in notes[0] and "--segment change" in notes[0]
    assert shape_notes(load_mesh(data_dir / "meshes" / "spot.obj"), "spot") == ()
    assert shape_notes(_mesh(trimesh.creation.box(extents=(0.5, 0.9, 0.4)), tmp_path), "a chair-sized box") == ()
