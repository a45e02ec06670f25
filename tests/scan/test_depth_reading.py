"""Scans say what they read: the depth range and the scale that gave it, and a warning when the kept object
is implausibly small for those depths (millimetre depth in a TUM-layout folder, read at TUM's 5000)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from kinetre.cli import main
from kinetre.errors import BadScanError
from kinetre.scan.depth_reading import SMALL_IN_VIEW, DepthReading, depth_reading, sample_depths, size_warning

pytest.importorskip("open3d")

import scan_synthetic as synthetic  # noqa: E402

RANGE = re.compile(r"depth: read ([\d.]+)-([\d.]+) m \(median ([\d.]+) m\) at depth scale (\d+) raw units per "
                   r"metre \(([^)]*)\)")


def as_tum(folder: Path, color: str = "color") -> Path:
    """Add TUM's rgb.txt and depth.txt to a Redwood folder (same files, TUM layout; its depth stays in mm)."""
    depth = sorted((folder / "depth").iterdir())
    color_files = sorted((folder / color).iterdir())
    (folder / "rgb.txt").write_text("".join(f"{i / 30:.6f} {color}/{p.name}\n" for i, p in enumerate(color_files)))
    (folder / "depth.txt").write_text("".join(f"{i / 30:.6f} depth/{p.name}\n" for i, p in enumerate(depth)))
    return folder


@pytest.fixture(scope="module")
def lamp_tum(tmp_path_factory):
    """The 56 cm desk lamp orbited at about 1.1 m, millimetre depth, in a TUM-layout folder."""
    orbit = synthetic.render_orbit("lamp", 20, 640, 480, seed=4)
    return as_tum(orbit.write(tmp_path_factory.mktemp("lamp") / "frames"))


def test_redwood_frames_in_a_tum_folder_report_the_range_read_at_tums_scale(tmp_path, data_dir, capsys):
    source = data_dir / "rgbd" / "redwood_livingroom"
    folder = tmp_path / "tum"
    folder.mkdir()
    for name in ("color", "depth"):
        (folder / name).symlink_to(source / name)
    (folder / "intrinsics.json").write_bytes((source / "camera_primesense.json").read_bytes())
    as_tum(folder)
    assert main(["scan", str(folder), "-o", str(tmp_path / "room.ply"), "--quiet"]) == 0
    out = capsys.readouterr().out
    near, far, median, scale, origin = RANGE.search(out).groups()
    raw = np.concatenate([np.asarray(Image.open(p)).ravel() for p in sorted((source / "depth").iterdir())])
    raw = raw[raw > 0].astype(float)
    assert int(scale) == 5000 and origin == "the TUM layout's default"
    for got, q in ((near, 1), (median, 50), (far, 99)):
        assert abs(float(got) - np.percentile(raw, q) / 5000) < 0.01 + 0.02 * float(got)
    assert float(median) < 0.4                               # a living room within 40 cm: the scale is wrong


@pytest.mark.slow
def test_the_wrong_scale_warns_of_a_fragment_and_the_right_one_does_not(lamp_tum, tmp_path, capsys):
    assert main(["scan", str(lamp_tum), "-o", str(tmp_path / "wrong.ply"), "--segment", "plane", "--quiet"]) == 0
    captured = capsys.readouterr()
    near, far, median, scale, origin = RANGE.search(captured.out).groups()
    assert int(scale) == 5000 and 0.15 < float(median) < 0.3       # 1.1 m read five times too near
    warning = re.search(r"kinetre scan: warning: the kept object is ([\d.]+) cm across, (\d+) % of the view's",
                        captured.err)
    assert warning and float(warning.group(1)) < 15 and int(warning.group(2)) < 100 * SMALL_IN_VIEW
    assert "--depth-scale 1000 reads the median at" in captured.err

    assert main(["scan", str(lamp_tum), "-o", str(tmp_path / "right.ply"), "--segment", "plane", "--quiet",
                 "--depth-scale", "1000"]) == 0
    captured = capsys.readouterr()
    near, far, median, scale, origin = RANGE.search(captured.out).groups()
    assert int(scale) == 1000 and origin == "given" and 0.9 < float(median) < 1.5
    assert "warning" not in captured.err
    kept = re.search(r"kept: \d+ vertices, \d+ faces, (\d+) x (\d+) x (\d+) cm", captured.out).groups()
    assert 50 <= max(map(int, kept)) <= 60                     # the whole 56 cm lamp


@pytest.mark.slow
def test_a_scene_that_vanishes_at_the_wrong_scale_is_a_clear_error(tmp_path):
    orbit = synthetic.render_orbit("lamp", 16, 320, 240, seed=4)
    folder = as_tum(orbit.write(tmp_path / "frames"))
    from kinetre.scan.pipeline import scan
    # read at 5000 the 33 x 56 x 20 cm lamp is 7 x 11 x 4 cm (13.6 cm corner to corner); at 2 cm voxels a
    # speck is anything under 4 joins of 2 voxels, 16 cm: every piece of it goes, and that must be said
    with pytest.raises(BadScanError, match=r"nothing was left .*at depth scale 5000 .*--depth-scale 1000 reads "
                                           r"the median at 1\.\d\d m"):
        scan(folder, tmp_path / "x.ply", segment="plane", voxel=0.02, progress=False)


def test_the_warning_compares_the_object_with_the_view_at_the_median_depth():
    reading = depth_reading([np.full(10, 2.0, np.float32), np.array([1.0, 3.0, 0.5], np.float32)], 1000.0,
                            "given", 2.5)
    assert reading.median == 2.0 and reading.beyond == pytest.approx(1 / 13)
    view = 2.0 * 640 / 500.0                                  # 2.56 m wide at 2 m with fx = 500
    assert size_warning(reading, SMALL_IN_VIEW * view * 1.01, 640, 500.0) is None
    text = size_warning(reading, 0.2, 640, 500.0)
    assert "20.0 cm across, 8 % of the view's 256 cm width" in text
    assert "--depth-scale 5000 reads the median at 0.40 m" in text
    assert "beyond 2.5 m" in reading.line()
    depth = np.zeros((64, 64), np.float32)
    depth[::16, ::16] = 1.5
    depth[0, 0] = 0.0
    assert sample_depths(depth).tolist() == [1.5] * 15
    assert size_warning(DepthReading(0, 0, 0, 0, 3, 1000, "given"), 0.01, 640, 500.0) is None


@pytest.mark.slow
def test_animate_takes_the_scans_options_and_says_what_it_read(lamp_tum, tmp_path, data_dir, capsys):
    walk = str(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    common = ["--motion", walk, "--max-frames", "3", "--nodes", "32", "-q"]
    assert main(["animate", str(lamp_tum), *common, "--intrinsics", str(tmp_path / "none.json"),
                 "-o", str(tmp_path / "x.bvh")]) == 2
    assert "none.json: intrinsics file not found" in capsys.readouterr().err
    assert main(["animate", str(lamp_tum), *common, "--voxel", "0.5", "-o", str(tmp_path / "x.bvh")]) == 2
    assert "voxel size must be in (0, 0.2]" in capsys.readouterr().err

    assert main(["animate", str(lamp_tum), "--motion", walk, "--max-frames", "3", "--nodes", "32",
                 "-o", str(tmp_path / "wrong.bvh")]) == 0
    captured = capsys.readouterr()
    assert "at depth scale 5000 raw units per metre (the TUM layout's default)" in captured.out
    assert "kinetre: warning:" in captured.err and "--depth-scale 1000 reads the median at" in captured.err

    assert main(["animate", str(lamp_tum), "--motion", walk, "--max-frames", "3", "--nodes", "32",
                 "--depth-scale", "1000", "--intrinsics", str(lamp_tum / "intrinsics.json"), "--voxel", "0.012",
                 "-o", str(tmp_path / "right.bvh")]) == 0
    captured = capsys.readouterr()
    near, far, median, scale, origin = RANGE.search(captured.out).groups()
    assert int(scale) == 1000 and origin == "given" and "warning" not in captured.err
