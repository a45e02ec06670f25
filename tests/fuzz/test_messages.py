"""Fuzzing the studio's message parser (studio/protocol.py): arbitrary bytes, arbitrary JSON and bent versions of
each well-formed client message. Every message is either parsed into values a command can use (finite numbers,
ids in range) or refused with a ProtocolError; nothing else escapes. Pure Python, so it runs in this process."""
from __future__ import annotations

import json
import math
import os

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz import mutate
from fuzz import seeding as seeds
from kinetre.studio import protocol

EXAMPLES = int(os.environ.get("KINETRE_FUZZ_EXAMPLES", "10")) * 10  # cheap: no reader process, no files
SETTINGS = settings(max_examples=EXAMPLES, derandomize=os.environ.get("KINETRE_FUZZ_LONG") != "1", database=None,
                    deadline=None, suppress_health_check=list(HealthCheck))
MESSAGES = seeds.messages()
JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
                    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=8), inner, max_size=5),
                    max_leaves=30)


def parse_all(raw: bytes) -> None:
    """What the studio does with one message before a command runs: each answer is a value or a ProtocolError."""
    try:
        msg = protocol.parse_message(raw)
    except protocol.ProtocolError:
        return
    assert isinstance(msg, dict) and isinstance(msg["type"], str)
    for parse in (protocol.parse_person, protocol.parse_mesh):
        try:
            value = parse(msg)
        except protocol.ProtocolError:
            continue
        assert value is None or (type(value) is int and 1 <= value <= protocol.MAX_PERSON or parse is protocol.parse_mesh
                                 and type(value) is int and value >= 1)
    if msg["type"] == "place":
        try:
            scale, position, yaw = protocol.parse_place(msg)
        except protocol.ProtocolError:
            return
        lo, hi = protocol.SCALE_RANGE
        assert lo <= scale <= hi and abs(yaw) <= protocol.MAX_YAW
        assert all(abs(v) <= protocol.ROOM for v in position)
    if msg["type"] == "skeleton":
        try:
            frame = protocol.parse_frame(msg)
        except protocol.ProtocolError:
            return
        sk = frame.skeleton
        assert (np.abs(sk.positions[sk.tracked]) <= protocol.ROOM).all()
        assert math.isfinite(frame.t) and frame.seq >= 0
        if frame.hands is not None:
            assert frame.hands.shape == (2, 21, 3)
        if frame.blendshapes is not None:
            assert ((frame.blendshapes >= 0) & (frame.blendshapes <= 1)).all()


@SETTINGS
@given(st.binary(max_size=256))
def test_arbitrary_bytes_are_parsed_or_refused(raw):
    parse_all(raw)


@SETTINGS
@given(JSON, st.sampled_from([m["type"] for m in MESSAGES] + ["", "x"]))
def test_arbitrary_json_is_parsed_or_refused(value, kind):
    parse_all(json.dumps(value).encode())
    if isinstance(value, dict):
        parse_all(json.dumps({**value, "type": kind}).encode())


@SETTINGS
@given(st.sampled_from(MESSAGES).flatmap(lambda m: mutate.json_mutation(m, max_ops=4)))
def test_bent_client_messages_are_parsed_or_refused(msg):
    parse_all(mutate.json_text(msg))


@SETTINGS
@given(st.sampled_from(MESSAGES).map(mutate.json_text).flatmap(mutate.text_mutation))
def test_broken_message_text_is_parsed_or_refused(raw):
    parse_all(raw)


def test_every_seed_message_parses():
    for msg in MESSAGES:
        parse_all(json.dumps(msg).encode())
    frame = protocol.parse_frame(MESSAGES[0])
    assert frame.hands is not None and frame.blendshapes is not None
