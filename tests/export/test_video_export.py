"""Video export: an H.264 (or VP9) file with one frame per pose at the take's rate, showing the mesh move."""
from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from kinetre.deform.pose import GraphPose
from kinetre.errors import ExportError
from kinetre.export.render import Camera
from kinetre.export.video import BONE_RGB, draw_skeletons, take_bounds, write_video
from kinetre.skeleton.models import Skeleton, SkeletonModel
from PIL import Image


def probe(path) -> dict:
    out = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-show_entries",
                          "stream=codec_name,width,height,r_frame_rate,nb_read_frames,pix_fmt", "-of", "json",
                          str(path)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)["streams"][0]


def decode(path, size=(640, 480)) -> np.ndarray:
    """(F, H, W, 3) uint8 frames decoded by ffmpeg."""
    raw = subprocess.run(["ffmpeg", "-v", "error", "-i", str(path), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
                         capture_output=True, check=True).stdout
    return np.frombuffer(raw, np.uint8).reshape(-1, size[1], size[0], 3)


def spine_skeletons(graph, poses):
    """A 2-joint skeleton along the capsule's axis that follows the take (for the overlay)."""
    model = SkeletonModel("stick", ("base", "tip"), (-1, 0))
    ends = (np.argmin(graph.nodes[:, 2]), np.argmax(graph.nodes[:, 2]))
    out = []
    for pose in poses:
        m = pose.node_matrices(graph.nodes)
        moved = [m[j, :3, :3] @ graph.nodes[j] + m[j, :3, 3] for j in ends]
        out.append([Skeleton(model, np.array(moved), np.ones(2, bool))])
    return out


@pytest.mark.slow
def test_mp4_has_every_frame_at_the_take_rate_and_shows_motion(tmp_path, capsule_take):
    mesh, graph, poses, fps = capsule_take
    out = tmp_path / "take.mp4"
    seen = []
    write_video(out, mesh, graph, poses, fps, skeletons=spine_skeletons(graph, poses), on_frame=seen.append)
    assert seen == list(range(len(poses)))
    info = probe(out)
    assert info["codec_name"] == "h264" and info["pix_fmt"] == "yuv420p"
    assert (info["width"], info["height"]) == (640, 480)
    assert info["r_frame_rate"] == "24/1" and int(info["nb_read_frames"]) == len(poses)

    frames = decode(out).astype(np.int16)
    # the bend peaks mid-take: consecutive frames differ, and the middle differs a lot from the start
    step = np.abs(np.diff(frames, axis=0)).mean(axis=(1, 2, 3))
    assert (step > 0.05).all(), step
    assert np.abs(frames[len(frames) // 2] - frames[0]).mean() > step.max()
    # the picture is not empty: sky at the top, ground, a lit mesh and the blue skeleton overlay
    mid = frames[len(frames) // 2]
    assert mid[:20].reshape(-1, 3).std(axis=0).max() < 3                                           # clear sky band at the top
    blue = (np.abs(mid - np.array(BONE_RGB)).max(axis=2) < 40).sum()
    assert blue > 200
    Image.fromarray(mid.astype(np.uint8)).save(tmp_path / "middle.png")


def test_webm_and_odd_rates(tmp_path, capsule_take):
    mesh, graph, poses, _ = capsule_take
    out = tmp_path / "take.webm"
    write_video(out, mesh, graph, poses[:5], 30000 / 1001, size=(320, 240))   # NTSC 29.97
    info = probe(out)
    assert info["codec_name"] == "vp9" and (info["width"], info["height"]) == (320, 240)
    assert info["r_frame_rate"] == "30000/1001" and int(info["nb_read_frames"]) == 5


def test_camera_frames_the_whole_take(capsule_take):
    mesh, graph, poses, _ = capsule_take
    lo, hi = take_bounds(mesh, graph, poses)
    assert lo[1] <= mesh.vertices[:, 1].min() + 1e-9
    cam = Camera(lo, hi, (640, 480))
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    px = cam.project(corners, (640, 480))
    assert (px >= 0).all() and (px[:, 0] <= 640).all() and (px[:, 1] <= 480).all()


def test_overlay_draws_only_tracked_bones():
    frame = np.zeros((120, 160, 3), np.uint8)
    cam = Camera(np.array([-1.0, 0.0, -1.0]), np.array([1.0, 2.0, 1.0]), (160, 120))
    model = SkeletonModel("stick", ("a", "b", "c"), (-1, 0, 1))
    pos = np.array([[0, 0.2, 0], [0, 1.0, 0], [0, 1.8, 0]])
    both = draw_skeletons(frame, [Skeleton(model, pos, np.array([True, True, True]))], cam)
    lost = draw_skeletons(frame, [Skeleton(model, pos, np.array([True, True, False]))], cam)
    assert (both != 0).any(axis=2).sum() > (lost != 0).any(axis=2).sum() > 0


def test_bad_requests_raise_export_errors(tmp_path, capsule_take):
    mesh, graph, poses, fps = capsule_take
    with pytest.raises(ExportError, match=r"take\.avi: a video must end in \.mp4 or \.webm"):
        write_video(tmp_path / "take.avi", mesh, graph, poses, fps)
    with pytest.raises(ExportError, match="even numbers"):
        write_video(tmp_path / "take.mp4", mesh, graph, poses, fps, size=(641, 480))
    with pytest.raises(ExportError, match="no frames"):
        write_video(tmp_path / "take.mp4", mesh, graph, [], fps)
    with pytest.raises(ExportError, match="2 skeleton frames for 12 poses"):
        write_video(tmp_path / "take.mp4", mesh, graph, poses, fps, skeletons=[[], []])
    bad = [GraphPose(poses[0].rotations, np.full_like(poses[0].translations, np.inf))]
    with pytest.raises(ExportError, match=r"take\.mp4: .*non-finite"):
        write_video(tmp_path / "take.mp4", mesh, graph, bad, fps)
    (tmp_path / "file").write_text("x")
    with pytest.raises(ExportError, match="cannot create the folder"):
        write_video(tmp_path / "file" / "take.mp4", mesh, graph, poses[:2], fps)
