"""Segmentation: RANSAC plane, voxel components, change between two TSDFs."""
from __future__ import annotations

import numpy as np
import pytest

from kinetre.errors import BadScanError
from kinetre.scan.frames import Intrinsics
from kinetre.scan.fuse import Voxels
from kinetre.scan.segment import (Plane, changed_voxels, dominant_plane, focus_point, group_components,
                                  largest_voxel_component, remove_floaters, remove_plane, select_object,
                                  seen_free)
from kinetre.scan.surface import ScanMesh

import scan_synthetic as synthetic


def test_dominant_plane_among_clutter_faces_the_camera():
    rng = np.random.default_rng(0)
    floor = np.c_[rng.uniform(-1, 1, 3000), rng.normal(0, 0.002, 3000), rng.uniform(-1, 1, 3000)]
    clutter = rng.uniform([-0.2, 0.0, -0.2], [0.2, 0.4, 0.2], (800, 3))
    plane = dominant_plane(np.r_[floor, clutter], viewpoint=np.array([0.0, 1.0, 2.0]), distance=0.01)
    assert abs(plane.normal @ [0, 1, 0]) == pytest.approx(1.0, abs=1e-3)
    assert plane.normal[1] > 0 and abs(plane.offset) < 0.005
    np.testing.assert_allclose(plane.distance(np.array([[0.0, 0.3, 0.0]])), [0.3], atol=0.005)


def test_remove_plane_keeps_largest_component_above():
    # a floor quad at y = 0, a tall quad strip above it, and a small scrap above it too
    v = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1],
                  [0, 0.1, 0], [0.3, 0.1, 0], [0.3, 0.5, 0], [0, 0.5, 0],
                  [0.8, 0.1, 0.8], [0.82, 0.1, 0.8], [0.82, 0.12, 0.8]], float)
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [8, 9, 10]])
    mesh = ScanMesh(v, f, np.zeros((len(v), 3), np.float32))
    kept = remove_plane(mesh, Plane(np.array([0.0, 1.0, 0.0]), 0.0), margin=0.05)
    assert len(kept.faces) == 2 and kept.vertices[:, 1].min() == pytest.approx(0.1)
    with pytest.raises(BadScanError, match="nothing is left above"):
        remove_plane(mesh, Plane(np.array([0.0, 1.0, 0.0]), -1.0), margin=0.05)


def test_largest_voxel_component_uses_26_neighbours():
    line = np.array([[i, i, i] for i in range(5)])  # corner-connected diagonal: one component
    blob = np.array([[20, 0, 0], [21, 0, 0]])
    result = largest_voxel_component(np.r_[blob, line])
    assert sorted(map(tuple, result)) == sorted(map(tuple, line))


def _voxels(keys, tsdf, weight=None):
    keys = np.asarray(keys, np.int64)
    return Voxels(keys, np.asarray(tsdf, np.float32),
                  np.ones(len(keys), np.float32) if weight is None else np.asarray(weight, np.float32), 0.01)


def test_changed_voxels_finds_the_object_and_which_scan_has_it():
    grid = np.stack(np.meshgrid(range(10), range(10), [0], indexing="ij"), -1).reshape(-1, 3)
    floor = _voxels(grid, np.zeros(len(grid)))
    cube = np.stack(np.meshgrid(range(3, 6), range(3, 6), range(1, 4), indexing="ij"), -1).reshape(-1, 3)
    # with the object: the floor plus a cube of surface voxels (tsdf ~ 0); without: those voxels are free (+1)
    with_object = _voxels(np.r_[grid, cube], np.r_[np.zeros(len(grid)), np.full(len(cube), -0.1)])
    without = _voxels(np.r_[grid, cube], np.r_[np.zeros(len(grid)), np.ones(len(cube))])
    removed = changed_voxels(with_object, without)
    assert sorted(map(tuple, removed.keys)) == sorted(map(tuple, cube)) and not removed.object_in_after
    assert changed_voxels(without, with_object).object_in_after
    with pytest.raises(BadScanError, match="do not differ"):
        changed_voxels(floor, floor)


def test_seen_free_uses_depth_frames():
    camera = Intrinsics(8, 6, 8.0, 8.0, 3.5, 2.5)
    depth = np.full((6, 8), 2.0, np.float32)
    points = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.99], [0.0, 0.0, 3.0], [5.0, 0.0, 1.0]])
    free = seen_free(points, [(depth, np.eye(4), camera)], margin=0.02)
    assert free.tolist() == [True, False, False, False]


def _quad(x0, length=0.3, y=0.1):
    """A 1 cm wide strip from x0 to x0 + length at height y: two faces."""
    v = np.array([[x0, y, 0], [x0 + length, y, 0], [x0 + length, y, 0.01], [x0, y, 0.01]], float)
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _mesh_of(*parts):
    vertices, faces, offset = [], [], 0
    for v, f in parts:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    v = np.concatenate(vertices)
    return ScanMesh(v, np.concatenate(faces), np.zeros((len(v), 3), np.float32))


def test_pieces_of_a_broken_thin_part_are_one_object_and_the_focus_picks_it():
    # an arm broken by a 1 cm gap (within the join distance), a big slab 0.5 m away, a speck next to the arm
    arm = _mesh_of(_quad(0.0), _quad(0.31), _quad(0.62, 0.002))
    groups = group_components(arm, join=0.012)
    assert len(np.unique(groups)) == 1
    assert len(np.unique(group_components(arm, join=0.004))) == 3
    slab = _mesh_of(_quad(0.0), _quad(0.31), *[_quad(1.2 + 0.01 * i, 0.5) for i in range(20)])
    poses = [synthetic.look_at((2 * np.sin(a), 1.0, 2 * np.cos(a)), (0.3, 0.1, 0.0)) for a in np.linspace(0, 6, 8)]
    focus = focus_point(np.array(poses))
    np.testing.assert_allclose(focus, [0.3, 0.1, 0.0], atol=1e-6)
    choice = select_object(slab, focus, join=0.012)
    assert choice.sizes == [40, 4] and choice.kept == 4 and "nearest to the point" in choice.reason
    assert select_object(slab, None, join=0.012).kept == 40  # no focus: the largest
    assert focus_point(np.array([poses[0], poses[0]])) is None  # parallel axes fix no point
    kept, dropped = remove_floaters(arm, 0.02, join=0.012)
    assert len(kept.faces) == 4 and dropped == [2]  # the 2 mm speck goes, both halves of the arm stay


def test_a_cluster_of_specks_at_the_focus_is_passed_over_for_the_object():
    # what a scene shrunk by a wrong depth scale leaves: scraps 2 mm long right where the cameras looked,
    # each under SPECK_JOINS joins across (so remove_floaters would drop them all), and the object 10 cm off
    scraps = [_quad(0.01 * i, 0.002, 0.5) for i in range(6)]
    mesh = _mesh_of(_quad(0.0, 0.3, 0.6), *scraps)
    focus = np.array([0.02, 0.5, 0.0])
    assert len(np.unique(group_components(mesh, join=0.012))) == 2
    choice = select_object(mesh, focus, join=0.012)
    assert choice.sizes == [12, 2] and choice.kept == 2 and "passed over 1 made only of specks" in choice.reason
    kept, dropped = remove_floaters(choice.mesh, 0.02, join=0.012)
    assert len(kept.faces) == 2 and dropped == []
    only_scraps = select_object(_mesh_of(*scraps), focus, join=0.012)  # nothing else: nothing better to keep
    assert only_scraps.kept == 12 and remove_floaters(only_scraps.mesh, 0.02, join=0.012)[0].faces.size == 0
