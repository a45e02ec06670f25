"""A motion file uploaded to the studio (POST /api/motion, the page's "Motion…" entry) plays in a loop as the
sample motion and possesses the mesh: a VRM Animation Kinetre wrote plays its own joints."""
import asyncio

import httpx
import numpy as np
import pytest

from kinetre.cli import main
from kinetre.errors import BadMotionError
from kinetre.motion.source import load_take
from kinetre.studio.player import read_motion
from studio.studio_ws import StudioClient


@pytest.fixture(scope="module")
def vrma(tmp_path_factory, data_dir):
    out = tmp_path_factory.mktemp("motion") / "walk.vrma"
    assert main(["avatar", str(data_dir / "avatars" / "CesiumMan.glb"), "--motion",
                 str(data_dir / "bvh" / "cmu_12_01_walk.bvh"), "--max-frames", "24", "-o", str(out), "-q"]) == 0
    return out


def test_a_vrma_reads_as_the_joints_it_holds_with_the_travel_removed(vrma):
    frames, fps = read_motion("walk.vrma", vrma.read_bytes())
    take = load_take(vrma)
    assert fps == 30.0 and len(frames) == len(take) == 24
    travel = take.positions[:, 0] - take.positions[0, 0]
    for k in (0, 11, 23):
        moved = take.positions[k].copy()
        moved[:, [0, 2]] -= travel[k, [0, 2]]
        assert np.allclose(frames[k].positions, moved, atol=1e-9)
    assert np.ptp(np.stack([f.positions[0, [0, 2]] for f in frames]), axis=0).max() < 1e-9


def test_files_that_cannot_play_are_named(data_dir):
    with pytest.raises(BadMotionError, match=r"^notes.txt: not a motion file the studio plays"):
        read_motion("notes.txt", b"hello")
    with pytest.raises(BadMotionError, match=r"^Fox.glb#Survey: its skeleton .* is not a humanoid"):
        read_motion("Fox.glb", (data_dir / "avatars" / "Fox.glb").read_bytes())
    with pytest.raises(BadMotionError, match=r"^broken.vrma: "):
        read_motion("broken.vrma", b"glTF not really")


def test_an_uploaded_vrma_plays_and_possesses_the_mesh(studio, vrma):
    r = httpx.post(studio + "/api/motion?name=walk.vrma", content=vrma.read_bytes(), timeout=120)
    assert r.status_code == 200, r.text
    assert r.json() == {"motion": "walk.vrma", "frames": 24, "fps": 30.0}

    async def go():
        async with StudioClient(studio) as c:
            def sample(c):
                return next((u for u in c.state["users"] if u["client"] == "sample"), None)
            await c.wait(lambda c: sample(c) and sample(c)["possessing"], 120)
            seen, before = c.transform_count, np.array(c.transforms[4])
            await c.wait(lambda c: c.transform_count >= seen + 5, 60)
            return sample(c), before, np.array(c.transforms[4])

    user, before, after = asyncio.run(go())
    assert user["frames"] >= 1
    assert np.abs(after - before).max() > 1e-3          # the mesh's nodes move with the walk
    bad = httpx.post(studio + "/api/motion?name=notes.txt", content=b"hello")
    assert bad.status_code == 400 and bad.json()["error"].startswith("notes.txt: not a motion file")

