"""End to end: synthetic ground truth (Chamfer, trajectory, segmentation) and the real Redwood frames."""
from __future__ import annotations

import io
import shutil
import zipfile

import numpy as np
import pytest
import trimesh

import kinetre
from kinetre.errors import BadScanError
from kinetre.scan.pipeline import ScanResult, scan, scan_zip
from kinetre.scan.surface import ScanMesh, component_count

import scan_synthetic as synthetic
from scan_synthetic import REDWOOD, to_world


def _mesh(path) -> trimesh.Trimesh:
    return trimesh.load(path, force="mesh", process=False)


@pytest.mark.slow
def test_trajectory_error_under_2cm(spot_scene, spot_plane_scan):
    _, poses, *_ = spot_scene
    truth = np.linalg.inv(poses[0]) @ poses  # world of the scan = first camera
    error = np.linalg.norm(spot_plane_scan.poses[:, :3, 3] - truth[:, :3, 3], axis=1)
    rmse = float(np.sqrt(np.mean(error ** 2)))
    print(f"trajectory RMSE {rmse * 1000:.1f} mm, max {error.max() * 1000:.1f} mm")
    assert spot_plane_scan.frames_used == len(poses) and spot_plane_scan.frames_rejected == 0
    assert rmse <= 0.02 and error.max() <= 0.03


def test_chamfer_to_true_object_under_1cm(spot_scene, spot_plane_scan):
    scene, poses, k, _, _, exact, masks = spot_scene
    mesh = _mesh(spot_plane_scan.mesh_path)
    vertices = to_world(np.asarray(mesh.vertices), spot_plane_scan.transform, poses[0])
    accuracy = synthetic.surface_distance(vertices, scene.object_vertices, scene.object_faces)
    # completeness over the true surface the camera saw (exact depth, object pixels), above the 2 cm band
    # that plane removal cuts away by design
    seen = synthetic.seen_points(poses, exact, masks, k, stride=7)
    seen = seen[seen[:, 1] > 0.025]
    completeness = synthetic.surface_distance(seen, vertices, np.asarray(mesh.faces))
    chamfer = 0.5 * (accuracy.mean() + completeness.mean())
    print(f"Chamfer mean {chamfer * 1000:.2f} mm (accuracy {accuracy.mean() * 1000:.2f} mm, "
          f"completeness {completeness.mean() * 1000:.2f} mm)")
    assert chamfer <= 0.01
    assert np.percentile(accuracy, 90) <= 0.02


def test_plane_segmentation_removes_floor_and_keeps_one_object(spot_plane_scan, spot_scene):
    scene = spot_scene[0]
    mesh = _mesh(spot_plane_scan.mesh_path)
    vertices = np.asarray(mesh.vertices)
    assert component_count(ScanMesh(vertices, np.asarray(mesh.faces), np.zeros_like(vertices))) == 1
    # +Y up with the floor at y = 0: nothing of the floor is left, the object stands on it
    assert vertices[:, 1].min() > 0.01
    height = np.ptp(scene.object_vertices[:, 1])
    assert abs(vertices[:, 1].max() - height) < 0.02
    # the floor slab is 1.2 m wide; the object's footprint is the cow's (0.4 m long)
    assert np.ptp(vertices[:, [0, 2]], axis=0).max() < 0.45
    assert spot_plane_scan.vertices == len(vertices)


def test_scan_mesh_loads_and_builds_a_graph(spot_plane_scan):
    mesh = kinetre.load_mesh(spot_plane_scan.mesh_path)
    graph = kinetre.build_graph(mesh, nodes=32, seed=0)
    assert len(graph.nodes) == 32
    # normals outward: the object's surface, seen from above and from the cameras, faces up on top
    normals = np.asarray(_mesh(spot_plane_scan.mesh_path).face_normals)
    centres = np.asarray(_mesh(spot_plane_scan.mesh_path).triangles_center)
    top = centres[:, 1] > np.percentile(centres[:, 1], 90)
    assert np.mean(normals[top, 1] > 0) > 0.8


@pytest.mark.slow
def test_lost_frame_is_rejected_and_never_fused(spot_scene, tmp_path):
    scene, poses, k, colors, depths, _, _ = spot_scene
    colors, depths = list(colors[:6]), list(depths[:6])
    # frame 3 is from somewhere else: a wall 0.5 m in front of the camera with its own texture
    rng = np.random.default_rng(3)
    depths[3] = np.full_like(depths[3], 0.5) + rng.normal(0, 0.002, depths[3].shape).astype(np.float32)
    colors[3] = rng.integers(0, 255, colors[3].shape, dtype=np.uint8)
    folder = synthetic.write_redwood(tmp_path / "frames", colors, depths, k, k[0, 2] * 2 + 1, k[1, 2] * 2 + 1)
    result = scan(folder, tmp_path / "out.ply", voxel=0.01, progress=False)
    assert result.frames_rejected == 1 and result.frames_used == 5
    assert not result.accepted[3] and result.accepted[[0, 1, 2, 4, 5]].all()
    truth = np.linalg.inv(poses[0]) @ poses[:6]
    error = np.linalg.norm(result.poses[:, :3, 3] - truth[:, :3, 3], axis=1)[[0, 1, 2, 4, 5]]
    assert error.max() < 0.02
    # the wall never entered the model: nothing was reconstructed at 0.5 m in front of camera 3
    vertices = to_world(np.asarray(_mesh(result.mesh_path).vertices), result.transform, poses[0])
    wall_distance = np.abs((vertices - poses[3][:3, 3]) @ poses[3][:3, 2] - 0.5)
    scene_distance = np.minimum(synthetic.surface_distance(vertices, scene.object_vertices, scene.object_faces),
                                synthetic.surface_distance(vertices, scene.other_vertices[0], scene.other_faces[0]))
    assert np.mean(scene_distance < 0.02) > 0.97
    assert np.count_nonzero((wall_distance < 0.01) & (scene_distance > 0.03)) == 0


@pytest.mark.slow
def test_change_segmentation_isolates_the_removed_object(tmp_path):
    # two static boxes stay put: a bare floor alone cannot anchor the second sweep to the first
    scene = synthetic.spot_on_plane(clutter=True)
    poses = synthetic.orbit(6, arc_degrees=40.0)
    k = synthetic.camera_matrix(320, 240)
    # scan the cow, take it away, scan again: the object is what changed
    with_cow = synthetic.render(scene, poses, k, 320, 240, seed=4)
    empty = synthetic.render(synthetic.empty_plane(clutter=True), poses[::-1], k, 320, 240, seed=5)
    before = synthetic.write_redwood(tmp_path / "with_cow", with_cow[0], with_cow[1], k, 320, 240)
    after = synthetic.write_redwood(tmp_path / "empty", empty[0], empty[1], k, 320, 240)
    result = scan(after, tmp_path / "cow.glb", segment="change", before=before, voxel=0.01, progress=False)
    mesh = _mesh(result.mesh_path)
    vertices = to_world(np.asarray(mesh.vertices), result.transform, poses[0])  # world = first camera of --before
    distance = synthetic.surface_distance(vertices, scene.object_vertices, scene.object_faces)
    print(f"change: {len(vertices)} vertices, mean distance to the cow {distance.mean() * 1000:.1f} mm")
    assert np.mean(distance < 0.02) > 0.9
    assert np.ptp(vertices[:, 1]) > 0.25  # most of the cow's height, not a sliver
    assert component_count(ScanMesh(np.asarray(mesh.vertices), np.asarray(mesh.faces),
                                    np.zeros_like(mesh.vertices))) == 1


@pytest.mark.slow
def test_real_redwood_frames_reconstruct_the_room(tmp_path):
    out = tmp_path / "room.obj"
    result = scan(REDWOOD, out, voxel=0.02, progress=False)
    assert isinstance(result, ScanResult) and result.frames_used == 5 and result.frames_rejected == 0
    mesh = kinetre.load_mesh(out)
    extent = np.ptp(np.asarray(mesh.vertices), axis=0)
    # the depth spans 0.95-2.7 m over a 57x43 degree view: a room corner a few metres across
    assert result.vertices > 5000
    assert 1.5 < extent.max() < 5.0 and extent.min() > 0.5
    # tracking agrees with the trajectory shipped with the frames (odometry.log, camera-to-world)
    rows = [line.split() for line in (REDWOOD / "odometry.log").read_text().splitlines() if line.strip()]
    truth = np.array([[[float(x) for x in rows[i * 5 + j]] for j in range(1, 5)] for i in range(5)])
    truth = np.linalg.inv(truth[0]) @ truth
    error = np.linalg.norm(result.poses[:, :3, 3] - truth[:, :3, 3], axis=1)
    assert error.max() < 0.02


def test_scan_zip_from_bytes(tiny_frames, tmp_path):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for path in tiny_frames.rglob("*"):
            if path.is_file():
                archive.write(path, "upload/" + str(path.relative_to(tiny_frames)))
    result = scan_zip(buffer.getvalue(), tmp_path / "zip.ply", voxel=0.02)
    assert result.frames_used == 3 and result.vertices > 100
    assert result.mesh_path.is_file()
    with pytest.raises(BadScanError, match="not a readable zip"):
        scan_zip(b"not a zip", tmp_path / "bad.ply")
    empty = io.BytesIO()
    with zipfile.ZipFile(empty, "w") as archive:
        archive.writestr("readme.txt", "nothing here")
    with pytest.raises(BadScanError, match="no RGB-D frames"):
        scan_zip(empty.getvalue(), tmp_path / "none.ply")


def test_scan_option_errors(tiny_frames, tmp_path):
    with pytest.raises(BadScanError, match="needs --before"):
        scan(tiny_frames, tmp_path / "a.ply", segment="change")
    with pytest.raises(BadScanError, match="unknown segmentation"):
        scan(tiny_frames, tmp_path / "a.ply", segment="sphere")
    with pytest.raises(BadScanError, match="voxel size"):
        scan(tiny_frames, tmp_path / "a.ply", voxel=0.0)
    with pytest.raises(kinetre.ExportError, match="must end in"):
        scan(tiny_frames, tmp_path / "a.stl", voxel=0.02, progress=False)
    shutil.rmtree(tiny_frames / "missing", ignore_errors=True)
    with pytest.raises(BadScanError, match="not found"):
        scan(tiny_frames / "missing", tmp_path / "a.ply")
