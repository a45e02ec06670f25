"""FBX through Blender's own exporter: `kinetre animate … -o out.fbx` and `kinetre avatar … -o out.fbx`, imported
back by Blender's FBX importer (fbx_probe.py), deform like the same take written as glTF (played by the
independent tests/export/gltf_player.py) at sampled frames; where Blender is not installed the command says so
in one line before doing any work."""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from export.gltf_player import GltfFile
from kinetre.cli import main

PROBE = Path(__file__).resolve().parent / "fbx_probe.py"
FRAMES = 6
SAMPLED = (0, 2, 5)
needs_blender = pytest.mark.skipif(shutil.which("blender") is None, reason="Blender is not installed (make setup does)")


@pytest.fixture(scope="module")
def probed(tmp_path_factory, data_dir):
    tmp = tmp_path_factory.mktemp("fbx")
    walk = data_dir / "bvh" / "cmu_12_01_walk.bvh"
    common = ["--max-frames", FRAMES, "--fps", 30, "-q"]
    cases = {"possessed": ["animate", data_dir / "meshes" / "spot.obj", "--motion", walk, "--nodes", 48],
             "avatar": ["avatar", data_dir / "avatars" / "CesiumMan.glb", "--motion", walk]}
    for name, argv in cases.items():
        for ext in (".fbx", ".glb"):
            extra = ["--exact-joints"] if ext == ".glb" and name == "possessed" else []
            assert main([str(a) for a in argv + ["-o", tmp / f"{name}{ext}", *common, *extra]]) == 0
    job = {"fps": 30, "fbx": [{"path": str(tmp / f"{name}.fbx"), "frames": list(SAMPLED)} for name in cases]}
    (tmp / "job.json").write_text(json.dumps(job))
    subprocess.run(["blender", "-b", "--factory-startup", "--python", str(PROBE), "--", str(tmp / "job.json"),
                    str(tmp / "out.json")], capture_output=True, timeout=900, check=True)
    out = json.loads((tmp / "out.json").read_text())["fbx"]
    return {name: (tmp / f"{name}.glb", res) for name, res in zip(cases, out)}


@needs_blender
@pytest.mark.parametrize("kind", ["possessed", "avatar"])
def test_the_fbx_deforms_like_the_gltf(probed, kind):
    glb, res = probed[kind]
    player = GltfFile(glb)
    first = player.vertices(0.0)
    height = np.ptp(first[:, 1])
    blender = [np.array(f) for f in res["frames"]]
    assert len(blender[0]) == len(first)
    gap, match = cKDTree(first).query(blender[0])   # FBX keeps its own vertex order: matched where they stand
    assert gap.max() < 1e-4 * height
    moved = 0.0
    for k, frame in enumerate(SAMPLED):
        ours = player.vertices(frame / 30)[match]
        assert np.abs(blender[k] - ours).max() < 1e-4 * height, (frame, np.abs(blender[k] - ours).max() / height)
        moved = max(moved, np.abs(ours - first[match]).max())
    assert moved > 0.01 * height
    assert res["bones"] > 0


def test_without_blender_the_command_says_so(tmp_path, data_dir, monkeypatch, capsys):
    monkeypatch.setenv("KINETRE_BLENDER", str(tmp_path / "no-blender"))
    walk = str(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    for argv in (["animate", str(data_dir / "meshes" / "spot.obj")], ["avatar", str(data_dir / "avatars" / "CesiumMan.glb")]):
        assert main(argv + ["--motion", walk, "-o", str(tmp_path / "out.fbx")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "FBX is written through Blender's own exporter and Blender is not installed" in err
        assert "out.fbx" in err and not (tmp_path / "out.fbx").exists()
    monkeypatch.delenv("KINETRE_BLENDER")
    monkeypatch.setenv("PATH", str(tmp_path))
    assert main(["animate", str(data_dir / "meshes" / "spot.obj"), "--motion", walk, "-o", str(tmp_path / "o.fbx")]) == 2
    assert "no `blender` on PATH" in capsys.readouterr().err
