"""A hand puppet in a real browser (tests/e2e/driver_puppet.mjs): the fake camera shows a standing woman with
both hands in view (../shared/data/images/pose/standing_woman.png, held for a few seconds); the page, opened
with ?puppet=right, possesses the five-legged creature with her right hand."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
from e2e.node_driver import run_driver
from studio.conftest import start_server
from synthetic import hand_creature

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
WOMAN = ROOT / ".." / "shared" / "data" / "images" / "pose" / "standing_woman.png"


def test_the_right_hand_possesses_the_mesh_from_the_page(tmp_path):
    assert (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file(), "run `make web` first"
    assert shutil.which("ffmpeg"), "ffmpeg is needed (make setup installs it)"
    camera = tmp_path / "woman.y4m"
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-loop", "1", "-i", str(WOMAN.resolve()), "-t", "4", "-r", "30",
                    "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p", "-f", "yuv4mpegpipe",
                    str(camera)], check=True, timeout=120)
    mesh = tmp_path / "creature.obj"
    hand_creature()[0].export(mesh)
    proc, url = start_server(str(mesh), nodes=64, sample_motion=False)
    try:
        r = run_driver("driver_puppet.mjs", {"url": url, "video": str(camera), "artifacts": str(HERE / "artifacts")},
                       600)
    finally:
        proc.terminate()
        proc.wait(60)
    assert r["errors"] == [] and r["chosen"] == "right"
    me = r["me"]
    assert me is not None and me["possessing"] and me["hand"] == "right", r["message"]
    assert len(me["attached"]) >= 5, me["attached"]            # of the hand's 21 joints
    assert "(right hand)" in r["status"]
    samples = np.array(r["samples"], dtype=np.float64)
    assert samples.shape[1] > 0 and np.isfinite(samples).all()
