"""Motion quality and cleaning end to end: `kinetre capture` of the public dance clip (`video/pose_1.mp4`,
stance on one foot between knee lifts), `kinetre info`, and `kinetre avatar` / `kinetre animate --report`.

The clip is tracked once per session (MediaPipe is CPU heavy) as tracked (`--raw`); the commands that read a
camera take clean it by default, and their reports give its quality as tracked and as cleaned."""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from kinetre.cli import main
from kinetre.motion.cleanup import clean_take
from kinetre.motion.contact import contact_joints, detect_stance
from kinetre.motion.quality import take_quality
from kinetre.motion.stream import read_stream
from synthetic import body_mesh


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def dance(data_dir, tmp_path_factory):
    """pose_1.mp4 tracked as it comes (no filter), its path."""
    path = tmp_path_factory.mktemp("dance") / "raw.kinetre.jsonl"
    code = main(["capture", "--video", str(data_dir / "video" / "pose_1.mp4"), "--raw", "--people", "1",
                 "--no-hands", "--no-face", "-q", "-o", str(path)])
    assert code == 0
    return path


def test_the_dance_is_cleaned_with_numbers(dance):
    raw = read_stream(dance)
    assert raw.applied is None and len(raw) == 120
    clean = clean_take(raw)
    assert set(clean.applied) >= {"smoothing", "contact"}
    feet = contact_joints(clean.model, clean.positions)
    stance = detect_stance(clean.positions, clean.fps, feet, viewpoint=np.zeros(3))
    # she stands on one foot while the other knee lifts: a foot is down most of the clip
    assert stance.mask.any(axis=1).mean() > 0.6
    before, after = take_quality(raw, stance), take_quality(clean, stance, reference=raw)
    assert before.slide_p95 > 5.0 and after.slide_p95 <= 1.0 and after.bob_p95 <= 1.0, (before, after)
    assert after.jitter <= before.jitter / 2
    assert abs(after.lag_ms) <= 1000 / 30


def test_info_prints_the_quality(capsys, dance):
    code, out, err = run(capsys, "info", dance)
    assert code == 0, err
    assert "quality:" in out and "jitter" in out and "foot skate" in out and "FootLeft, FootRight" in out


def test_capture_cleans_by_default_and_records_it(capsys, data_dir, tmp_path):
    out_path = tmp_path / "clean.kinetre.jsonl"
    code, out, err = run(capsys, "capture", "--video", data_dir / "video" / "pose_1.mp4", "--max-frames", 30,
                         "--people", "1", "--no-hands", "--no-face", "-o", out_path)
    assert code == 0, err
    assert "cleaned by smoothing and contact" in out
    take = read_stream(out_path)
    assert take.applied["offline"] and take.applied["contact"]["joints"] == ["FootLeft", "FootRight"]
    code, out, _ = run(capsys, "info", out_path)
    assert "cleaned: smoothing and contact" in out


@pytest.mark.slow
def test_avatar_report_measures_its_feet(capsys, dance, data_dir, tmp_path):
    report = tmp_path / "avatar.json"
    code, out, err = run(capsys, "avatar", data_dir / "avatars" / "CesiumMan.glb", "--motion", dance,
                         "-o", tmp_path / "a.glb", "--report", report)
    assert code == 0, err
    assert "cleaned the take: smoothing and contact" in out
    rep = json.loads(report.read_text())
    assert rep["take_as_tracked"]["jitter"] > 2 * rep["take"]["jitter"]
    assert rep["take"]["slide_p95"] <= 1.0 < rep["take_as_tracked"]["slide_p95"]
    feet = rep["avatar_feet"]
    assert len(feet["contacts"]) == 2 and feet["jitter"] > 0
    code, _, err = run(capsys, "avatar", data_dir / "avatars" / "CesiumMan.glb", "--motion", dance, "--raw",
                       "-o", tmp_path / "b.glb", "--report", tmp_path / "raw.json")
    raw = json.loads((tmp_path / "raw.json").read_text())
    assert code == 0 and raw["applied"] is None and "take_as_tracked" not in raw
    assert feet["slide_p95"] < raw["avatar_feet"]["slide_p95"]


def test_animate_report_measures_the_mesh_contacts(capsys, dance, tmp_path):
    mesh = tmp_path / "body.obj"
    body = body_mesh()
    trimesh.Trimesh(body.vertices, body.faces, process=False).export(mesh)
    report = tmp_path / "animate.json"
    code, out, err = run(capsys, "animate", mesh, "--motion", dance, "--nodes", 64, "--max-frames", 40,
                         "-o", tmp_path / "out.glb", "--report", report, "-q")
    assert code == 0, err
    rep = json.loads(report.read_text())
    mc = rep["mesh_contacts"]
    assert mc["contacts"] == ["mesh region 1", "mesh region 2"]  # the two soles
    assert mc["frames"] == 40 and mc["slide_p95"] is not None


def test_contact_opts_in_for_mocap_and_raw_contradicts_it(capsys, data_dir, tmp_path):
    walk = data_dir / "bvh" / "cmu_12_01_walk.bvh"
    out_path = tmp_path / "walk.kinetre.jsonl"
    code, out, err = run(capsys, "animate", data_dir / "meshes" / "spot.obj", "--motion", walk, "--contact",
                         "-o", out_path, "--report", tmp_path / "r.json")
    assert code == 0, err
    rep = json.loads((tmp_path / "r.json").read_text())
    assert "contact" in rep["applied"] and "smoothing" not in rep["applied"]
    assert rep["take"]["slide_p95"] < rep["take_as_tracked"]["slide_p95"]
    code, _, err = run(capsys, "animate", data_dir / "meshes" / "spot.obj", "--motion", walk, "--contact", "--raw",
                       "-o", out_path)
    assert code == 2 and "--raw and --contact" in err


def test_camera_capture_cleans_live_and_records_it(capsys, data_dir, tmp_path, monkeypatch):
    import kinetre.motion.capture as capture
    opened = capture._open
    # the dance clip plays the webcam (OpenCV opens a file as it opens a camera)
    monkeypatch.setattr(capture, "_open", lambda source, label: opened(str(data_dir / "video" / "pose_1.mp4"), label))
    out_path = tmp_path / "camera.kinetre.jsonl"
    code, out, err = run(capsys, "capture", "--camera", 0, "--max-frames", 20, "--no-hands", "--no-face", "-o",
                         out_path)
    assert code == 0, err
    take = read_stream(out_path)
    assert len(take) == 20 and take.applied["offline"] is False
    assert take.applied["smoothing"]["pass"] == "causal" and "contact" in take.applied
    assert (take.main_person() >= 0).mean() > 0.9  # the main person's frames are their cleaned crowd entries
