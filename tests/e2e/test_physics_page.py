"""Physics play in a real browser (tests/e2e/driver_physics.mjs): boxes fall when the cow goes through the
tower, reset by key and by voice, dodgeball throws balls, a take replays into a 30 fps WebM, and an added
mesh's proxies join the world.

Screenshots land in tests/e2e/artifacts/ (physics-*.png). Needs the built page and web/node_modules.
"""
from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pytest
from e2e.node_driver import run_driver
from studio.conftest import start_server
from physics.node_replay import bundle, node_replay
from studio.fixtures_voice import looped_command_wav

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


@pytest.fixture(scope="module")
def reset_wav(tmp_path_factory):
    """Festival saying "reset", then silence (the fake microphone loops it)."""
    return looped_command_wav("reset", tmp_path_factory.mktemp("voice"))


def test_boxes_fall_reset_dodgeball_and_replay_to_video(reset_wav, tmp_path):
    assert (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file(), "run `make web` first"
    proc, url = start_server(nodes=128, sample_motion=True)
    try:
        config = {"url": url, "audio": str(reset_wav), "artifacts": str(HERE / "artifacts"),
                  "out": str(tmp_path / "replay.webm"), "takeTransforms": str(tmp_path / "take.transforms"),
                  "takeMesh": str(tmp_path / "mesh.json"), "add": str(ROOT / "src" / "kinetre" / "data" / "spot.obj")}
        r = run_driver("driver_physics.mjs", config, 400)
    finally:
        proc.terminate()
        proc.wait(60)

    start, hit = r["start"], r["hit"]
    assert start["spheres"] > 20 and len(start["boxes"]) == 20 and len(start["meshes"]) == 1
    edge = 2 * min(b[1] for b in start["boxes"])  # the bottom boxes stand on the ground
    levels = sorted({round(b[1] / edge - 0.5) for b in start["boxes"]})
    assert levels == [0, 1, 2, 3, 4]  # a standing tower of 5
    fallen = sum(after[1] < before[1] - edge / 2 for before, after in zip(start["boxes"], hit["boxes"]))
    assert hit["knockedDown"] >= 10 and fallen >= 5  # boxes came down, not just slid
    assert all(b[1] > 0 for b in hit["boxes"])  # on the ground, not through it
    assert hit["showSpheres"] and len(hit["proxies"]) == 8

    assert r["resetByKey"]["knockedDown"] == 0
    voice = r["resetByVoice"]
    assert voice["heard"] == "reset" and voice["before"] >= 5 and voice["knockedDown"] == 0
    assert voice["rebuilt"] >= 1  # the voice command rebuilt the world
    assert r["dodgeball"]["balls"] >= 3 and r["dodgeball"]["boxes"] == 0

    replay = r["replay"]
    assert replay["frames"] >= 20 and replay["boxes"] == 20
    assert [m["id"] for m in replay["meshes"]] == start["meshes"] == [r["take"]["id"]]
    assert r["take"]["file"].endswith(f"/take-mesh{r['take']['id']}.transforms")  # named by the mesh's id
    assert replay["steps"] == round((replay["frames"] - 1) * 2) + 60  # 1/60 s steps, then a second to settle
    probe = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v", "-show_entries",
                            "stream=codec_name,r_frame_rate,nb_read_frames", "-of", "json", config["out"]],
                           capture_output=True, text=True, check=True)
    stream = json.loads(probe.stdout)["streams"][0]
    assert stream["codec_name"] == "vp8" and stream["r_frame_rate"] == "30/1"
    assert int(stream["nb_read_frames"]) == math.ceil(replay["steps"] / 2) + 1  # one frame per 1/30 s

    # every mesh in the world: the added cow's proxies join the first's, and the list's choice takes the gizmo
    added = r["added"]
    assert added["meshes"] == added["ids"] and added["spheres"] == 2 * start["spheres"]
    assert added["selected"] == added["ids"][1]

    # the same take through the same TypeScript modules in node: the same world, bit for bit
    script = bundle(tmp_path / "replay_take.mjs")
    again = node_replay(script, Path(config["takeMesh"]), Path(config["takeTransforms"]), r["take"]["fps"], runs=1,
                        preset=replay["preset"], placement=replay["meshes"][0]["placement"])
    assert again["frames"] == replay["frames"]
    assert again["runs"][0]["knockedDown"] == replay["knockedDown"]
    assert again["runs"][0]["states"] == replay["states"]
