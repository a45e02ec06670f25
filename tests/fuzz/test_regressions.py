"""Files that once crashed or tracebacked a reader, kept from fuzzing: `kinetre info` (a separate process, so a
native crash shows as a signal) must refuse each with exit 2 and one line naming the file and the problem."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

CASES = Path(__file__).resolve().parent / "cases"
# file -> what the one-line message must say
EXPECTED = {
    # the compiled cleanup kernel indexed vertices by these unchecked: a segmentation fault
    "face-index-past-vertices.ply": "a face names vertex 99999999, but the mesh has 4 vertices",
    "negative-face-index.ply": "a face names vertex -5, but the mesh has 4 vertices",
    "huge-vertex-count.ply": "cannot parse PLY",
    # trimesh's glTF loader passes index data through unchecked: an IndexError traceback in its vertex merge
    "index-past-vertices.glb": "a face names vertex 65535, but the mesh has 8 vertices",
    # a keyframe time of 3.4e38 s: the sampler asked numpy for that many frames (a ValueError traceback)
    "animation-key-time-huge.glb": "lasts 3.403e+38 s, over 2097152 frames at 30 fps",
    # bent JSON: a reference to an object the file does not have
    "accessor-names-missing-buffer-view.glb": "not a valid glTF file: accessor 0 has a bad type, count, offset or "
                                              "buffer view",
}


def test_every_kept_case_has_its_expectation():
    assert sorted(p.name for p in CASES.iterdir()) == sorted(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_kinetre_info_refuses_the_case_in_one_line(name):
    path = CASES / name
    out = subprocess.run([sys.executable, "-X", "faulthandler", "-m", "kinetre.cli", "info", str(path)],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 2, f"exit {out.returncode}: {out.stderr[-2000:]}"
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and EXPECTED[name] in lines[0], out.stderr
