"""The studio page in a real browser: Debian's Chromium driven by playwright-core (tests/e2e/driver.mjs).

The fake camera plays a person dancing (../shared/data/video/pose_1_320x240_30fps.y4m), the fake
microphone festival's "possess". Screenshots land in tests/e2e/artifacts/ (gitignored).
Needs the built page (`make web`) and node + web/node_modules (`npm ci` in web/).
"""
from __future__ import annotations

from pathlib import Path

import pygltflib
import pytest
from e2e.node_driver import run_driver
from studio.conftest import start_server
from studio.fixtures_voice import looped_command_wav

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
ARTIFACTS = HERE / "artifacts"
VIDEO = ROOT / ".." / "shared" / "data" / "video" / "pose_1_320x240_30fps.y4m"


def drive(url: str, scenario: str, timeout: float = 600, **extra) -> dict:
    assert (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file(), "run `make web` first"
    config = {"scenario": scenario, "url": url + "/", "query": "?noshadows", "video": str(VIDEO),
              "artifacts": str(ARTIFACTS), **extra}
    return run_driver("driver.mjs", config, timeout)


@pytest.fixture(scope="module")
def studio_page():
    proc, url = start_server(nodes=128, sample_motion=True)
    yield url
    proc.terminate()
    proc.wait(60)


@pytest.fixture(scope="module")
def possess_wav(tmp_path_factory):
    """Festival saying "possess", then silence (the fake microphone loops it)."""
    return looped_command_wav("possess", tmp_path_factory.mktemp("voice"))


def test_the_sample_motion_plays_before_any_camera(studio_page):
    r = drive(studio_page, "sample")
    assert r["state"]["meshName"] == "spot.obj" and r["state"]["nodeCount"] > 100
    assert not r["state"]["cameraRunning"]
    assert any(u["client"] == "sample" and u["possessing"] for u in r["state"]["users"])
    assert r["spread"] > 0.005  # the walk moves the cow's vertices (metres)


def test_possess_move_record_release_and_voice(studio_page, possess_wav):
    r = drive(studio_page, "single", audio=str(possess_wav))
    steps = {s["step"]: s for s in r["steps"]}
    assert steps["page: pose detected"]["tracked"] >= 12
    assert r["rigging"]["attachable"] >= 1  # the rigging view highlights joints that would attach
    assert r["possessedSpread"] > 0.05  # possessed: vertices follow the dancer by more than 5 cm
    # the camera's frames are cleaned before the solve by default, and the page shows the user's meter,
    # renewed as frames come: smoothing adds at most a frame of lag (at the rate the page tracks) and, at a
    # camera's rate, removes jitter. At a few frames a second (SwiftShader on a busy machine) the dancer's own
    # motion is most of the acceleration between frames and a filter held to a frame of lag takes little of it
    # (bench_motion_quality measures the reduction at 30 fps)
    first, later = r["meter"]
    for m in (first, later):
        q = m["quality"]
        assert m["cleaning"] == ["smoothing", "contact"]
        assert q["fps"] < 10 or q["jitter"] < q["jitter_tracked"], q
        assert abs(q["lag_ms"]) <= 1000 / q["fps"] + 1
        removed = max(0, round(100 * (1 - q["jitter"] / q["jitter_tracked"])))  # the page shows no negative share
        assert f"your motion: jitter −{removed} %" in m["status"]
    assert later["quality"] != first["quality"]
    assert r["releasedSpread"] < 1e-4  # released: the mesh rests
    glb = pygltflib.GLTF2.load(r["glb"])
    assert len(glb.skins) == 1 and len(glb.skins[0].joints) == r["initial"]["nodeCount"]
    assert glb.animations and r["take"]["frames"] >= 10
    labels = {label for label, _ in r["downloads"]}
    assert labels == {"GLB", "BVH", "skeleton stream", "WebM"}  # the canvas video is offered too
    assert r["voice"]["possessing"] and r["voice"]["last"]["command"]["verb"] == "possess"


def test_two_capture_clients_drive_one_mesh(studio_page):
    r = drive(studio_page, "two")
    possessing = {u["client"]: u["subset"] for u in r["users"] if u["possessing"]}
    assert sorted(possessing.values()) == ["left leg", "right leg"]
    assert r["sameMesh"] and r["spreadA"] > 0.02


def test_loading_a_mesh_in_the_page(studio_page, data_dir, tmp_path):
    bad = tmp_path / "broken.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\n")
    r = drive(studio_page, "upload", bad=str(bad), good=str(data_dir / "meshes" / "teapot.obj"))
    assert r["badMessage"].startswith("broken.obj:") and "Traceback" not in r["badMessage"]
    assert r["after"]["meshName"] == "teapot.obj" and r["after"]["meshId"] == r["after"]["before"] + 1
