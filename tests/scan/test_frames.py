"""Frame folders: layouts, pairing, intrinsics, depth scale, and a clear error for each bad input."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from PIL import Image

from kinetre.errors import BadScanError
from kinetre.scan.frames import CAMERAS, Intrinsics, associate, open_sequence, read_frame, read_intrinsics

from scan_synthetic import REDWOOD


def test_redwood_folder_with_its_camera_json():
    sequence = open_sequence(REDWOOD)  # camera_primesense.json is the folder's only intrinsics file
    assert sequence.layout == "redwood" and len(sequence) == 5 and sequence.depth_scale == 1000.0
    assert sequence.intrinsics == Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
    color, depth = read_frame(sequence, 0)
    assert color.shape == (480, 640, 3) and color.dtype == np.uint8
    assert depth.shape == (480, 640) and depth.dtype == np.float32
    valid = depth[depth > 0]
    # MANIFEST: frame 0 spans 0.955-2.70 m, median 1.86 m
    assert valid.min() == pytest.approx(0.955, abs=0.01) and valid.max() == pytest.approx(2.70, abs=0.01)
    assert np.median(valid) == pytest.approx(1.86, abs=0.01)


def test_intrinsics_override_and_depth_scale(tmp_path):
    k = {"width": 640, "height": 480, "intrinsic_matrix": [500.0, 0, 0, 0, 510.0, 0, 320.0, 240.0, 1]}
    (tmp_path / "cam.json").write_text(json.dumps(k))
    sequence = open_sequence(REDWOOD, intrinsics=tmp_path / "cam.json", depth_scale=2000)
    assert (sequence.intrinsics.fx, sequence.intrinsics.fy, sequence.intrinsics.cx) == (500.0, 510.0, 320.0)
    _, half = read_frame(sequence, 0)
    _, full = read_frame(open_sequence(REDWOOD), 0)
    np.testing.assert_allclose(half * 2, full, rtol=1e-6)


def test_txt_intrinsics_and_named_camera(tmp_path):
    (tmp_path / "k.txt").write_text("525 0 319.5\n0 525 239.5\n0 0 1\n")
    assert read_intrinsics(tmp_path / "k.txt", (640, 480)) == CAMERAS["primesense"]
    frames = _redwood_copy(tmp_path / "frames", json_files=False)
    assert open_sequence(frames, camera="kinect").intrinsics == CAMERAS["kinect"]
    # a named 640x480 camera scales with a half-resolution sequence
    half = CAMERAS["kinect"].scaled(320, 240)
    assert (half.fx, half.cx, half.cy) == (262.5, 159.5, 119.5)


def _redwood_copy(folder, json_files=True):
    shutil.copytree(REDWOOD, folder, ignore=None if json_files else shutil.ignore_patterns("*.json"))
    return folder


def _write_tum(folder, depth_stamps, rgb_stamps, scale=5000.0):
    folder.mkdir()
    (folder / "rgb").mkdir()
    (folder / "depth").mkdir()
    lines_d, lines_c = ["# depth maps"], ["# color images"]
    for i, t in enumerate(depth_stamps):
        depth = np.full((12, 16), round((1.0 + i * 0.1) * scale), np.uint16)
        Image.fromarray(depth).save(folder / "depth" / f"{t:.6f}.png")
        lines_d.append(f"{t:.6f} depth/{t:.6f}.png")
    for i, t in enumerate(rgb_stamps):
        Image.fromarray(np.full((12, 16, 3), i, np.uint8)).save(folder / "rgb" / f"{t:.6f}.png")
        lines_c.append(f"{t:.6f} rgb/{t:.6f}.png")
    (folder / "depth.txt").write_text("\n".join(lines_d) + "\n")
    (folder / "rgb.txt").write_text("\n".join(lines_c) + "\n")
    (folder / "intrinsics.json").write_text(json.dumps(
        {"width": 16, "height": 12, "intrinsic_matrix": [13.0, 0, 0, 0, 13.0, 0, 7.5, 5.5, 1]}))
    return folder


def test_tum_pairs_by_nearest_timestamp(tmp_path):
    depth_stamps = [10.000, 10.033, 10.066]
    rgb_stamps = [9.990, 10.025, 10.036, 10.070, 10.200]  # extra and jittered colour frames
    sequence = open_sequence(_write_tum(tmp_path / "tum", depth_stamps, rgb_stamps))
    assert sequence.layout == "tum" and sequence.depth_scale == 5000.0 and len(sequence) == 3
    assert [p.name for p in sequence.color_paths] == ["9.990000.png", "10.036000.png", "10.070000.png"]
    color, depth = read_frame(sequence, 1)
    assert depth[0, 0] == pytest.approx(1.1, abs=1e-4) and color[0, 0, 0] == 2


def test_associate_is_one_to_one():
    match = associate(np.array([1.0, 1.01, 2.0]), np.array([1.005, 3.0]))
    assert match.tolist() == [0, -1, -1]


def test_bad_inputs_each_get_their_error(tmp_path):
    with pytest.raises(BadScanError, match="frames folder not found"):
        open_sequence(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BadScanError, match="no RGB-D frames"):
        open_sequence(tmp_path / "empty")
    (tmp_path / "nodepth" / "depth").mkdir(parents=True)
    with pytest.raises(BadScanError, match="no depth frames"):
        open_sequence(tmp_path / "nodepth")

    mismatched = _redwood_copy(tmp_path / "mismatched")
    (mismatched / "color" / "00004.jpg").unlink()
    with pytest.raises(BadScanError, match="5 depth images .* but 4 colour images"):
        open_sequence(mismatched)

    no_camera = _redwood_copy(tmp_path / "no_camera", json_files=False)
    with pytest.raises(BadScanError, match="no camera intrinsics"):
        open_sequence(no_camera)
    (no_camera / "broken.json").write_text("{}")
    with pytest.raises(BadScanError, match="no camera intrinsics"):  # not a PinholeCameraIntrinsic: ignored
        open_sequence(no_camera)
    with pytest.raises(BadScanError, match="not an Open3D PinholeCameraIntrinsic"):
        open_sequence(no_camera, intrinsics=no_camera / "broken.json")

    eight_bit = _redwood_copy(tmp_path / "eight_bit")
    depth = np.asarray(Image.open(eight_bit / "depth" / "00002.png"))
    Image.fromarray((depth // 20).astype(np.uint8)).save(eight_bit / "depth" / "00002.png")
    with pytest.raises(BadScanError, match=r"00002\.png: depth must be a 16-bit"):
        read_frame(open_sequence(eight_bit), 2)

    blank = _redwood_copy(tmp_path / "blank")
    Image.fromarray(np.zeros((480, 640), np.uint16)).save(blank / "depth" / "00001.png")
    with pytest.raises(BadScanError, match=r"00001\.png: empty depth frame"):
        read_frame(open_sequence(blank), 1)

    unpaired = _write_tum(tmp_path / "unpaired", [1.0, 2.0], [1.001, 5.0])
    with pytest.raises(BadScanError, match="1 of 2 depth frames in depth.txt have no colour frame"):
        open_sequence(unpaired)
    with pytest.raises(BadScanError, match="depth scale must be a positive"):
        open_sequence(REDWOOD, depth_scale=0)
    (no_camera / "broken.json").unlink()
    with pytest.raises(BadScanError, match="unknown camera 'hololens'"):
        open_sequence(no_camera, camera="hololens")


def test_a_tum_list_may_not_name_files_outside_its_folder_but_may_use_linked_folders(tmp_path):
    """An uploaded list naming ../ or an absolute path is refused; a folder linked in by the user is read."""
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    Image.new("I;16", (4, 4)).save(outside / "0.png")
    root = tmp_path / "frames"
    root.mkdir()
    (root / "depth").symlink_to(outside)
    (root / "depth.txt").write_text("0.0 depth/0.png\n")
    (root / "rgb.txt").write_text("0.0 depth/0.png\n")
    open_sequence(root, Intrinsics(4, 4, 2.0, 2.0, 2.0, 2.0))  # linked folder: fine
    for name in ("../elsewhere/0.png", str(outside / "0.png")):
        (root / "depth.txt").write_text(f"0.0 {name}\n")
        with pytest.raises(BadScanError, match="lies outside the frames folder"):
            open_sequence(root, Intrinsics(4, 4, 2.0, 2.0, 2.0, 2.0))
