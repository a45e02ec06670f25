"""Mesh clean-up: components, floaters, decimation, outward normals, rotations, files."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import kinetre
from kinetre.errors import ExportError
from kinetre.scan.surface import (ScanMesh, component_count, decimate, orient_outward, remove_small_components,
                                  write_mesh)


def _box(size=1.0, offset=(0.0, 0.0, 0.0), subdivisions=0) -> ScanMesh:
    box = trimesh.creation.box((size, size, size))
    for _ in range(subdivisions):
        box = box.subdivide()
    box.apply_translation(offset)
    return ScanMesh(np.asarray(box.vertices, float), np.asarray(box.faces, np.int64),
                    np.full((len(box.vertices), 3), 0.5, np.float32))


def _join(*meshes: ScanMesh) -> ScanMesh:
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return ScanMesh(np.concatenate([m.vertices for m in meshes]),
                    np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
                    np.concatenate([m.colors for m in meshes]))


def test_floaters_removed_and_largest_kept():
    big, small = _box(1.0, subdivisions=2), _box(0.05, (3.0, 0.0, 0.0))
    mesh = _join(big, small)
    assert component_count(mesh) == 2
    clean = remove_small_components(mesh, min_fraction=0.1)  # 12 faces < 10 % of 192
    assert component_count(clean) == 1 and len(clean.faces) == len(big.faces)
    np.testing.assert_allclose(clean.vertices, big.vertices)
    assert component_count(remove_small_components(mesh, min_fraction=0.01)) == 2
    assert len(remove_small_components(_join(small, big), largest_only=True).faces) == len(big.faces)


def test_decimate_reaches_target():
    mesh = _box(1.0, subdivisions=3)  # 768 faces
    small = decimate(mesh, 100)
    assert 80 <= len(small.faces) <= 100
    assert np.abs(small.vertices).max() == pytest.approx(0.5, abs=1e-6)  # a box stays a box
    assert decimate(mesh, 10_000) is mesh


def test_orient_outward_flips_an_inside_out_mesh():
    box = _box(1.0)
    inside_out = ScanMesh(box.vertices, box.faces[:, ::-1].copy(), box.colors)
    cameras = np.array([[0.0, 0.0, 3.0], [3.0, 1.0, 0.0]])
    fixed = orient_outward(inside_out, cameras)
    assert trimesh.Trimesh(fixed.vertices, fixed.faces).volume == pytest.approx(1.0)
    assert orient_outward(box, cameras) is box


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".glb"])
def test_written_mesh_loads_with_kinetre(tmp_path, suffix):
    mesh = _box(0.3, subdivisions=1)
    path = write_mesh(mesh, tmp_path / f"box{suffix}")
    loaded = kinetre.load_mesh(path)
    assert len(loaded.faces) == len(mesh.faces)
    assert np.ptp(np.asarray(loaded.vertices), axis=0) == pytest.approx([0.3, 0.3, 0.3], abs=1e-6)


def test_write_rejects_unknown_suffix(tmp_path):
    with pytest.raises(ExportError, match="must end in .ply, .obj, .glb"):
        write_mesh(_box(), tmp_path / "box.stl")
