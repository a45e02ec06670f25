"""Loading a mesh into a running studio: progress, readable errors, and the swap every page sees."""
import asyncio
import time

import httpx
import pytest
from studio.conftest import start_server
from studio.studio_ws import StudioClient


@pytest.fixture(scope="module")
def fresh_studio():
    proc, url = start_server(nodes=64)
    yield url
    proc.terminate()
    proc.wait(10)


def follow(url, job, timeout=180):
    stages = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        s = httpx.get(f"{url}/api/jobs/{job}").json()
        stages.append((s["stage"], s["fraction"]))
        if s["done"]:
            return s, stages
        time.sleep(0.05)
    raise TimeoutError(stages[-5:])


@pytest.mark.parametrize("name, content, expected", [
    ("points.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no triangles"),
    ("cut.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n", None),
    ("notes.txt", b"hello", "unsupported mesh format"),
])
def test_a_bad_file_gets_a_readable_error_and_the_mesh_stays(fresh_studio, name, content, expected):
    before = httpx.get(fresh_studio + "/api/state").json()["meshes"][0]["id"]
    r = httpx.post(f"{fresh_studio}/api/mesh?name={name}", content=content)
    assert r.status_code == 202
    status, _ = follow(fresh_studio, r.json()["job"])
    assert status["stage"] == "failed" and status["mesh"] is None
    message = status["error"]
    assert message.startswith(name) and "\n" not in message and "Traceback" not in message
    if expected is not None:
        assert expected in message
    assert "/tmp" not in message  # the server's temporary folder is not the user's business
    assert httpx.get(fresh_studio + "/api/state").json()["meshes"][0]["id"] == before


def test_empty_upload_is_refused(fresh_studio):
    r = httpx.post(f"{fresh_studio}/api/mesh?name=empty.stl", content=b"")
    assert r.status_code == 400 and "empty" in r.json()["error"]


def test_a_good_mesh_replaces_the_scene_for_every_client(fresh_studio, data_dir):
    data = (data_dir / "meshes" / "teapot.obj").read_bytes()

    async def go():
        async with StudioClient(fresh_studio) as c:
            before = c.state["meshes"][0]["id"]
            r = httpx.post(f"{fresh_studio}/api/mesh?name=teapot.obj", content=data, timeout=60)
            status, stages = await asyncio.to_thread(follow, fresh_studio, r.json()["job"])
            await c.wait(lambda c: c.state["meshes"][0]["id"] != before and c.transforms[1] == c.state["meshes"][0]["id"], 60)
            return before, status, stages, c.state, c.transforms

    before, status, stages, state, transforms = asyncio.run(go())
    assert status["error"] == "" and status["mesh"] == state["meshes"][0]["id"] == before + 1
    assert state["meshes"][0]["name"] == "teapot.obj" and 50 <= state["meshes"][0]["nodes"] <= 80
    fractions = [f for _, f in stages]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert transforms[4].shape[0] == state["meshes"][0]["nodes"]


def test_scan_entry_turns_a_zip_of_rgbd_frames_into_the_mesh(fresh_studio, data_dir, tmp_path):
    import zipfile
    frames = data_dir / "rgbd" / "redwood_livingroom"
    archive = tmp_path / "livingroom.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for f in sorted(frames.rglob("*")):
            if f.is_file() and f.suffix in (".jpg", ".png", ".json"):
                z.write(f, f.relative_to(frames))
    r = httpx.post(f"{fresh_studio}/api/mesh?name=livingroom.zip&voxel=0.03", content=archive.read_bytes())
    assert r.status_code == 202
    status, stages = follow(fresh_studio, r.json()["job"], timeout=600)
    assert not status["error"] and status["mesh"] is not None, status
    assert any(s.startswith("scanning") for s, _ in stages)
    state = httpx.get(fresh_studio + "/api/state").json()
    assert state["meshes"][0]["id"] == status["mesh"] and state["meshes"][0]["name"] == "livingroom.ply"


def test_scan_entry_refuses_a_bad_zip_readably(fresh_studio):
    r = httpx.post(f"{fresh_studio}/api/mesh?name=frames.zip", content=b"PK not really a zip")
    status, _ = follow(fresh_studio, r.json()["job"])
    assert status["stage"] == "failed" and "not a readable zip" in status["error"]
    assert "/tmp" not in status["error"]
