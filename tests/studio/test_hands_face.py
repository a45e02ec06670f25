"""Hands and face blendshapes from a capture page: the skeleton message's fields, checked by the server."""
from __future__ import annotations

import json

import numpy as np
import pytest

from kinetre.motion.capture import photo_people
from kinetre.skeleton.mediapipe import BLENDSHAPES
from kinetre.skeleton.models import KINECT20
from kinetre.studio.protocol import ProtocolError, parse_frame, skeleton_json
from studio.studio_ws import frame_message


WRISTS = [KINECT20.index("WristLeft"), KINECT20.index("WristRight")]
JAW = BLENDSHAPES.index("jawOpen")


@pytest.fixture(scope="module")
def hand_shape(data_dir):
    """(2, 21, 3) the standing woman's hands, each relative to its wrist (MediaPipe on a real photo)."""
    person = photo_people(data_dir / "images" / "pose" / "standing_woman.png")[0]
    assert np.isfinite(person.hands).all()
    return person.hands - person.hands[:, :1]


def sent_frames(walk, hand_shape, count):
    """Per frame i: (skeleton, hands at its wrists, blendshapes): the left hand lost every 5th frame, the face
    every 7th; jawOpen opens and closes."""
    out = []
    for i in range(count):
        sk = walk[i]
        hands = hand_shape + sk.positions[WRISTS][:, None]
        if i % 5 == 4:
            hands[0] = np.nan
        face = None
        if i % 7 != 6:
            face = np.round(np.linspace(0.0, 0.5, len(BLENDSHAPES)) * (i % 3) / 2, 4)
            face[JAW] = round(0.5 + 0.45 * np.sin(i / 3), 4)
        out.append((sk, hands, face))
    return out


def test_hands_and_blendshapes_survive_the_message_both_ways(walk, hand_shape):
    sk, hands, face = sent_frames(walk, hand_shape, 5)[4]
    frame = parse_frame(json.loads(skeleton_json("c1", 7, 12.5, sk, hands, face)))
    assert frame.seq == 7 and frame.t == 12.5
    assert np.isnan(frame.hands[0]).all()                      # the lost left hand: null on the wire
    np.testing.assert_array_equal(frame.hands[1], hands[1])
    np.testing.assert_array_equal(frame.blendshapes, face)
    plain = parse_frame(json.loads(skeleton_json("c1", 8, 13.0, sk)))
    assert plain.hands is None and plain.blendshapes is None


@pytest.mark.parametrize("fields, reason", [
    ({"hands": [None]}, "'hands' must be [left, right]"),
    ({"hands": [None, [[0.0, 1.0, 2.0]] * 20]}, "right hand must be 21"),
    ({"hands": [[[0.0, 1.0, True]] * 21, None]}, "left hand must be 21"),
    ({"hands": [[[0.0, 1.0, float("nan")]] * 21, None]}, "not finite"),
    ({"blendshapes": [0.1] * 51}, "must be 52 numbers"),
    ({"blendshapes": [0.1] * 25 + [float("nan")] + [0.1] * 26}, "'jawOpen' must be a weight in 0..1"),
    ({"blendshapes": [1.5] * 52}, "'_neutral' must be a weight in 0..1, got 1.5"),
])
def test_bad_hands_and_blendshapes_are_refused_by_name(walk, fields, reason):
    msg = {**json.loads(frame_message(1, walk[0])), **fields}
    with pytest.raises(ProtocolError, match=reason.replace("[", r"\[").replace("]", r"\]")):
        parse_frame(msg)
