"""`.kinetre.jsonl` takes: bit-exact round trips, incremental writing and every bad-input message."""
from __future__ import annotations

import io
import json

import numpy as np
import pytest

import kinetre
from kinetre.errors import BadMotionError
from kinetre.motion.bvh import load_bvh
from kinetre.motion.source import Take, load_take
from kinetre.motion.stream import TakeWriter, read_stream, write_stream


def awkward_take(seed=0, frames=7) -> Take:
    """Floats that a decimal format would round: 1/3, tiny, huge, negative zero; some joints untracked."""
    rng = np.random.default_rng(seed)
    pos = rng.normal(size=(frames, 20, 3)) / 3.0
    pos[0, 0] = [1.0 / 3.0, 5e-324, 1.7976931348623157e308]
    pos[1, 1] = [-0.0, 0.1 + 0.2, np.nextafter(1.0, 2.0)]
    tracked = rng.random((frames, 20)) > 0.2
    tracked[0, :2] = tracked[1, :2] = True
    pos[~tracked] = np.nan
    return Take(kinetre.KINECT20, pos, tracked, 29.97, "synthetic")


def test_round_trip_is_bit_exact(tmp_path):
    take = awkward_take()
    write_stream(tmp_path / "a.kinetre.jsonl", take)
    back = read_stream(tmp_path / "a.kinetre.jsonl")
    assert back.model is kinetre.KINECT20 and back.fps == 29.97 and back.source == "synthetic"
    np.testing.assert_array_equal(back.tracked, take.tracked)
    # same bits for every tracked coordinate (including -0.0 and the subnormal)
    assert back.positions[take.tracked].tobytes() == take.positions[take.tracked].tobytes()
    assert np.isnan(back.positions[~take.tracked]).all()
    # writing the read take again gives the same file, byte for byte
    write_stream(tmp_path / "b.kinetre.jsonl", back)
    assert (tmp_path / "a.kinetre.jsonl").read_bytes() == (tmp_path / "b.kinetre.jsonl").read_bytes()


def test_a_bvh_converts_and_replays_exactly(data_dir, tmp_path):
    take = load_bvh(data_dir / "bvh" / "mocapbank_test.bvh")
    write_stream(tmp_path / "m.kinetre.jsonl", take)
    back = load_take(tmp_path / "m.kinetre.jsonl")
    assert np.array_equal(back.positions, take.positions) and len(back) == 455


def test_generic_skeleton_keeps_its_hierarchy(data_dir, tmp_path):
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh", as_kinect=False).slice(0, 5)
    write_stream(tmp_path / "g.kinetre.jsonl", take)
    back = read_stream(tmp_path / "g.kinetre.jsonl")
    assert back.model == take.model and back.model.name == "bvh:cmu_12_01_walk"
    assert np.array_equal(back.positions, take.positions)


def test_format_lines(tmp_path):
    take = awkward_take(frames=2)
    write_stream(tmp_path / "f.kinetre.jsonl", take)
    lines = (tmp_path / "f.kinetre.jsonl").read_text().splitlines()
    head = json.loads(lines[0])
    assert head["format"] == "kinetre-take" and head["version"] == 1 and head["model"] == "kinect20"
    assert head["joints"][0] == "HipCenter" and head["parents"][:2] == [-1, 0] and head["fps"] == 29.97
    frame = json.loads(lines[2])
    assert frame["seq"] == 1 and frame["t"] == pytest.approx(1 / 29.97)
    untracked = [i for i, ok in enumerate(frame["tracked"]) if not ok]
    assert untracked and all(frame["positions"][i] is None for i in untracked)


def test_writer_writes_frame_by_frame():
    buf = io.StringIO()
    w = TakeWriter(buf, kinetre.KINECT20, 30.0, "camera 0")
    sk = kinetre.Skeleton.from_positions(kinetre.KINECT20, np.arange(60.0).reshape(20, 3))
    w.write(sk, t=0.25)
    w.write(sk)
    lines = buf.getvalue().splitlines()
    assert len(lines) == 3 and json.loads(lines[1])["t"] == 0.25 and json.loads(lines[2])["t"] == 1 / 30
    with pytest.raises(BadMotionError, match="got a 'openni17' frame"):
        w.write(kinetre.Skeleton.from_positions(kinetre.OPENNI17, np.zeros((17, 3))))


def test_list_of_frames_needs_fps(tmp_path):
    frames = awkward_take().frames()
    with pytest.raises(BadMotionError, match="needs their fps"):
        write_stream(tmp_path / "x.kinetre.jsonl", frames)
    write_stream(tmp_path / "x.kinetre.jsonl", frames, fps=60.0)  # how the studio calls it
    assert read_stream(tmp_path / "x.kinetre.jsonl").fps == 60.0


def _bad(tmp_path, text):
    p = tmp_path / "bad.kinetre.jsonl"
    p.write_text(text)
    with pytest.raises(BadMotionError) as info:
        read_stream(p)
    assert str(p) in str(info.value)
    return str(info.value)


def test_bad_takes(tmp_path):
    good = tmp_path / "good.kinetre.jsonl"
    write_stream(good, awkward_take(frames=3))
    head, *frames = good.read_text().splitlines()
    assert "empty file" in _bad(tmp_path, "")
    assert "line 1: not a kinetre take" in _bad(tmp_path, '{"format": "other"}\n')
    assert "line 1: not JSON" in _bad(tmp_path, "HIERARCHY\n")
    assert "unsupported take version 2" in _bad(tmp_path, head.replace('"version":1', '"version":2') + "\n")
    assert "header but no frames" in _bad(tmp_path, head + "\n")
    assert "line 3: not JSON" in _bad(tmp_path, "\n".join([head, frames[0], frames[1][:40]]))
    assert "line 3: seq must be an integer above 0, got 0" in _bad(tmp_path, "\n".join([head, frames[0], frames[0]]))
    short = json.loads(frames[0])
    short["positions"] = short["positions"][:19]
    assert "line 2: expected 20 positions and 20 tracked flags" in _bad(tmp_path, head + "\n" + json.dumps(short))
    wrong = json.loads(frames[0])
    wrong["positions"][0] = [1, 2]
    assert "joint 'HipCenter' position must be [x, y, z] or null" in _bad(tmp_path, head + "\n" + json.dumps(wrong))
    h = json.loads(head)
    h["joints"] = h["joints"][:19]
    assert "model 'kinect20' with joints or parents other than the built-in ones" in _bad(tmp_path, json.dumps(h))
    h = json.loads(head)
    h["fps"] = 0
    assert "fps must be a positive number" in _bad(tmp_path, json.dumps(h) + "\n" + frames[0])
    with pytest.raises(BadMotionError, match="no such file"):
        read_stream(tmp_path / "missing.kinetre.jsonl")
