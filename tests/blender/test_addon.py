"""The Blender add-on in Debian's Blender, headless: `kinetre blender-addon` writes the zip, Blender installs and
enables it, and its Possess and Release operators run on the sample cow as a user would (addon_probe.py):

* a broken motion file and a missing `kinetre` give Kinetre's one-line error as the report and change nothing;
* Possess with the sample walk brings back an action with one key per frame of the take at the scene's rate,
  on the same object, its material and its modifier kept, the armature modifier first;
* the mesh Blender evaluates matches Kinetre's own deformation (Eq. 2 with the solved R_j, t_j) of the mesh
  the add-on sent, within 0.01 % of the height, at sampled frames;
* Release leaves the object as it was.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import kinetre
from kinetre.animation import AnimateSettings, animate
from kinetre.cli import main
from kinetre.motion.source import load_take, resample

pytestmark = pytest.mark.skipif(shutil.which("blender") is None, reason="Blender is not installed (make setup does)")
PROBE = Path(__file__).resolve().parent / "addon_probe.py"
DATA = Path(kinetre.__file__).resolve().parent / "data"
FPS = 24
NODES = 96
SAMPLED = (0, 37, 90)


def blender_env(tmp: Path) -> dict[str, str]:
    """Blender with its user folders in `tmp` (the add-on installs there, not in the user's own Blender)."""
    return dict(os.environ, BLENDER_USER_SCRIPTS=str(tmp / "scripts"), BLENDER_USER_CONFIG=str(tmp / "config"))


@pytest.fixture(scope="module")
def probed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("addon")
    assert main(["blender-addon", "-o", str(tmp / "kinetre_blender.zip")]) == 0
    broken = tmp / "broken.bvh"
    broken.write_text("HIERARCHY\nROOT Hips\n{ OFFSET 0 0\n")
    job = {"zip": str(tmp / "kinetre_blender.zip"), "mesh": str(DATA / "spot.obj"),
           "motion": str(DATA / "cmu_12_01_walk.bvh"), "broken": str(broken), "fps": FPS, "nodes": NODES,
           "frames": list(SAMPLED), "obj": str(tmp / "sent.obj")}
    (tmp / "job.json").write_text(json.dumps(job))
    run = subprocess.run(["blender", "-b", "--factory-startup", "--python", str(PROBE), "--", str(tmp / "job.json"),
                          str(tmp / "out.json")], capture_output=True, text=True, timeout=1800, env=blender_env(tmp))
    assert (tmp / "out.json").is_file(), run.stdout[-3000:] + run.stderr[-3000:]
    return json.loads((tmp / "out.json").read_text()), tmp, broken


def test_the_addon_installs_and_enables(probed):
    out, _, _ = probed
    assert out["enabled"] and out["panel"]


def test_bad_input_is_one_line_in_the_report_and_changes_nothing(probed, capsys):
    out, tmp, broken = probed
    assert main(["animate", str(tmp / "sent.obj"), "--motion", str(broken), "-o", str(tmp / "x.glb")]) == 2
    cli_line = capsys.readouterr().err.strip()
    assert out["broken"]["result"] is None
    assert out["broken"]["error"].strip() == f"Error: {cli_line}"          # Kinetre's own line, no traceback
    assert "Traceback" not in out["broken"]["error"] and out["broken_unchanged"]
    assert "/nonexistent/bin/kinetre: no such program" in out["missing"]["error"]
    assert out["missing"]["error"].count("\n") <= 1 and out["missing_unchanged"]


def test_possess_brings_back_an_action_of_the_take_on_the_same_object(probed):
    out, _, _ = probed
    frames = len(resample(load_take(str(DATA / "cmu_12_01_walk.bvh")), FPS))
    assert out["possess"]["result"] == ["FINISHED"], out["possess"]
    assert out["keys"] == [frames] and out["frame_range"] == [0.0, frames - 1.0]
    after, before = out["after"], out["before"]
    assert after["meshes"] == before["meshes"] and after["materials"] == ["CowSkin"]
    assert after["modifiers"] == ["Kinetre", "Keep me"] and out["first_modifier"] == "ARMATURE"
    assert out["rig_of_modifier"] == out["rig"] == "Cow Kinetre rig"
    assert sorted(set(after["objects"]) - set(before["objects"])) == ["Cow Kinetre rig"]
    assert len(after["groups"]) >= NODES // 2 and out["bones"] >= len(after["groups"])


def test_blender_deforms_the_mesh_as_kinetre_does(probed):
    out, tmp, _ = probed
    mesh = kinetre.load_mesh(str(tmp / "sent.obj"))
    take = resample(load_take(str(DATA / "cmu_12_01_walk.bvh")), FPS)
    result = animate(mesh, take, AnimateSettings(nodes=NODES, up="y"))
    rest = np.array(out["rest"])
    assert len(rest) == len(result.mesh.vertices)
    assert np.abs(rest - result.mesh.vertices).max() < 1e-6 * np.ptp(rest[:, 1])   # the mesh sent, as sent
    height = np.ptp(rest[:, 1])
    moved = 0.0
    for frame in SAMPLED:
        ours = kinetre.skin(result.mesh, result.graph, result.poses[frame])
        theirs = np.array(out["frames"][str(frame)])
        assert np.abs(theirs - ours).max() < 1e-4 * height, (frame, np.abs(theirs - ours).max() / height)
        moved = max(moved, np.abs(ours - rest).max())
    assert moved > 0.01 * height                      # the take really moves the mesh


def test_release_restores_the_mesh(probed):
    out, _, _ = probed
    assert out["release"]["result"] == ["FINISHED"]
    released = dict(out["released"], objects=[o for o in out["released"]["objects"] if o != "Camera"])
    assert released == out["before"]
    assert out["released_moved"] == 0.0
