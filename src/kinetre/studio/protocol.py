"""The studio's JSON messages: control commands and skeleton frames, checked as they arrive.

Client → server (WebSocket text, JSON objects with a "type"):
    {"type": "skeleton", "seq": int, "t": ms, "model": "kinect20",
     "positions": [[x, y, z] × J] (metres, +Y up; null rows allowed), "tracked": [bool × J]}
    {"type": "possess", "subset": str | [str] | null, "hand": "left" | "right" | null}   {"type": "release"}
        (with "hand", that hand's landmarks (the skeleton frames' "hands") possess instead of the body)
    {"type": "subset", "subset": ...}   {"type": "place", "scale": s, "position": [3], "yaw": radians}
        (scale in 1e-3..1e3, position within ±50 m, yaw within ±2π: `check_placement`; tracked joints and hand
        landmarks also lie within ±50 m)
    {"type": "fit"}   {"type": "player", "on": bool}   {"type": "stats"}
    {"type": "subscribe", "skeletons": bool, "window": int}   (also receive the other users' skeleton
        frames; with window > 0 the server keeps at most that many messages unacknowledged)
    {"type": "ack", "received": int}   (messages of any kind received so far, counting from the welcome)
    "person": int (1..MAX_PERSON) on skeleton, possess, release, subset and fit: one of several people in
        the page's camera, a user of its own (named by `person_client`); without it, the page's own user
    A skeleton may add (a sender that tracks none leaves them out; readers that know only the body ignore them):
    "hands": [left, right], each null or 21 [x, y, z]: MediaPipe's hand landmarks in the skeleton's frame
        (metres, +Y up), the wrist at the body's wrist, as a take records them (docs/take-format.md)
    "blendshapes": [52 numbers in 0..1] in FaceLandmarker's order (`BLENDSHAPES`: "_neutral", then the 51
        ARKit names), or null
    "mesh": int on possess, fit and place: which of the scene's meshes (its id in the state's "meshes");
        without it, the first mesh, or for fit the mesh the user possesses

Server → client: JSON {"type": "welcome" | "state" | "skeleton" | "stats" | "error" | "progress", …}
and binary node-transform blocks (kinetre/wire/transforms.py).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from itertools import chain

import msgspec
import numpy as np

from ..errors import BadSkeletonError
from ..skeleton.mediapipe import BLENDSHAPES
from ..skeleton.models import MODELS, Skeleton

MAX_MESSAGE = 1 << 16  # bytes; a Kinect-20 frame is ~1.5 kB
# The physical bounds of what a client may ask of a shared scene (a mesh from a toy to a house, people in a
# room): outside them a command is refused naming its field, so no client can leave the scene unable to solve.
SCALE_RANGE = (1e-3, 1e3)
ROOM = 50.0  # metres: every coordinate of a placement, a tracked joint or a hand lies within ±ROOM
MAX_YAW = 2 * math.pi  # radians, a full turn either way
MAX_MESH = 1 << 20
_NUMBER_TYPES, _BOOL, _LIST, _THREE = {int, float}, {bool}, {list}, {3}
# Every client message is decoded on the server's event loop, a skeleton frame 30 times a second per camera:
# msgspec's decoder reads one several times faster than `json.loads`, into the same Python objects (the last of
# duplicate keys kept), so the checks below are unchanged.
_decode = msgspec.json.Decoder().decode


class ProtocolError(ValueError):
    """A client message that is not valid JSON or not a well-formed command (answered, never fatal)."""


def parse_message(text: str | bytes) -> dict:
    """Decode one client message; raises ProtocolError with a short reason."""
    if len(text) > MAX_MESSAGE:
        raise ProtocolError(f"message of {len(text)} bytes exceeds {MAX_MESSAGE}")
    try:
        msg = _decode(text)
    except msgspec.DecodeError:
        # what the fast decoder refuses, the standard one may still read (NaN, Infinity, lone surrogates):
        # the message then gets the same answer it always did
        try:
            msg = json.loads(text)
        except (ValueError, UnicodeDecodeError) as exc:
            raise ProtocolError(f"not JSON ({exc})") from None
    if not isinstance(msg, dict) or not isinstance(msg.get("type"), str):
        raise ProtocolError("expected a JSON object with a string 'type'")
    return msg


def _number(msg: dict, key: str) -> float:
    value = msg.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProtocolError(f"'{key}' must be a finite number, got {value!r}")
    return float(value)


def parse_skeleton(msg: dict) -> tuple[int, float, Skeleton]:
    """(seq, t, Skeleton) from a "skeleton" message; rows that are null or non-finite are untracked."""
    seq = _number(msg, "seq")
    if seq < 0 or seq != int(seq):
        raise ProtocolError(f"'seq' must be a non-negative integer, got {msg.get('seq')!r}")
    t = _number(msg, "t")
    model = MODELS.get(msg.get("model", "kinect20"))
    if model is None:
        raise ProtocolError(f"unknown skeleton model {msg.get('model')!r} (expected one of {', '.join(MODELS)})")
    rows, tracked = msg.get("positions"), msg.get("tracked")
    j = len(model.joints)
    if not isinstance(rows, list) or len(rows) != j:
        raise ProtocolError(f"'positions' must list {j} joints for {model.name}")
    if not isinstance(tracked, list) or len(tracked) != j or not set(map(type, tracked)) <= _BOOL:
        raise ProtocolError(f"'tracked' must list {j} booleans for {model.name}")
    # Type checks by set(map(type, ...)), iterated in C: this runs for every frame of every client. json.loads
    # yields only JSON types, and a bool is not a number here (type(), not isinstance()).
    present = [row for row in rows if row is not None]
    if (not set(map(type, present)) <= _LIST or not set(map(len, present)) <= _THREE
            or not set(map(type, chain.from_iterable(present))) <= _NUMBER_TYPES):
        bad = next(i for i, row in enumerate(rows) if row is not None and (
            type(row) is not list or len(row) != 3 or not set(map(type, row)) <= _NUMBER_TYPES))
        raise ProtocolError(f"joint {bad} of 'positions' must be [x, y, z] numbers or null")
    pos = np.full((j, 3), np.nan)
    try:
        if len(present) == j:
            pos[:] = rows
        elif present:
            pos[[i for i, row in enumerate(rows) if row is not None]] = present
    except OverflowError:  # an integer beyond float range
        raise ProtocolError("a joint position is out of range") from None
    outside = np.flatnonzero((np.abs(pos) > ROOM).any(axis=1))  # NaN rows (untracked) compare false
    if outside.size:
        raise ProtocolError(f"joint {outside[0]} of 'positions' lies outside the room (±{ROOM:g} m)")
    try:
        skeleton = Skeleton(model, pos, np.asarray(tracked, dtype=bool))
    except BadSkeletonError as exc:
        raise ProtocolError(str(exc)) from None
    return int(seq), t, skeleton


HAND_POINTS = 21


@dataclass(frozen=True, eq=False)
class SkeletonFrame:
    """A parsed "skeleton" message: the body, and the hands and face when the sender tracks them.

    hands : (2, 21, 3) left and right hand landmarks (NaN rows for a hand not seen), or None
    blendshapes : (52,) weights in `BLENDSHAPES` order, or None without a face
    """

    seq: int
    t: float
    skeleton: Skeleton
    hands: np.ndarray | None = None
    blendshapes: np.ndarray | None = None


def parse_hands(value) -> np.ndarray | None:
    """(2, 21, 3) from a message's "hands" ([left, right], each null or 21 [x, y, z]); None for null."""
    if value is None:
        return None
    if type(value) is not list or len(value) != 2:
        raise ProtocolError("'hands' must be [left, right], each null or 21 [x, y, z]")
    out = np.full((2, HAND_POINTS, 3), np.nan)
    for side, marks in enumerate(value):
        if marks is None:
            continue
        name = ("left", "right")[side]
        if (type(marks) is not list or len(marks) != HAND_POINTS or not set(map(type, marks)) <= _LIST
                or not set(map(len, marks)) <= _THREE
                or not set(map(type, chain.from_iterable(marks))) <= _NUMBER_TYPES):
            raise ProtocolError(f"the {name} hand must be {HAND_POINTS} [x, y, z] numbers or null")
        try:
            out[side] = marks
        except OverflowError:
            raise ProtocolError(f"the {name} hand has a coordinate out of range") from None
        if not (np.abs(out[side]) <= ROOM).all():  # NaN fails too
            raise ProtocolError(f"the {name} hand has a coordinate that is not finite or outside the room "
                                f"(±{ROOM:g} m)")
    return out


def parse_blendshapes(value) -> np.ndarray | None:
    """(52,) from a message's "blendshapes" (weights in 0..1 in `BLENDSHAPES` order); None for null."""
    if value is None:
        return None
    if (type(value) is not list or len(value) != len(BLENDSHAPES)
            or not set(map(type, value)) <= _NUMBER_TYPES):
        raise ProtocolError(f"'blendshapes' must be {len(BLENDSHAPES)} numbers (in FaceLandmarker's order) or null")
    try:
        weights = np.array(value, dtype=np.float64)
    except OverflowError:
        raise ProtocolError("a blendshape weight is out of range") from None
    bad = np.flatnonzero(~((weights >= 0.0) & (weights <= 1.0)))  # NaN fails both
    if bad.size:
        raise ProtocolError(f"blendshape {BLENDSHAPES[bad[0]]!r} must be a weight in 0..1, got {value[bad[0]]!r}")
    return weights


def parse_frame(msg: dict) -> SkeletonFrame:
    """A "skeleton" message with its optional hands and blendshapes (see the module docstring)."""
    seq, t, skeleton = parse_skeleton(msg)
    return SkeletonFrame(seq, t, skeleton, parse_hands(msg.get("hands")), parse_blendshapes(msg.get("blendshapes")))


MAX_PERSON = 1 << 20


def parse_person(msg: dict) -> int | None:
    """The "person" of a message (a tracked person's stable id in the sender's camera), or None."""
    person = msg.get("person")
    if person is None:
        return None
    if type(person) is not int or not 1 <= person <= MAX_PERSON:
        raise ProtocolError(f"'person' must be an integer 1..{MAX_PERSON}, got {person!r}")
    return person


def parse_mesh(msg: dict) -> int | None:
    """The "mesh" of a message (a mesh id of the scene), or None for the first mesh."""
    mesh = msg.get("mesh")
    if mesh is None:
        return None
    if type(mesh) is not int or not 1 <= mesh <= MAX_MESH:
        raise ProtocolError(f"'mesh' must be a mesh id (an integer 1..{MAX_MESH}), got {mesh!r}")
    return mesh


def parse_place(msg: dict) -> tuple[float, list, float]:
    """A "place" message's (scale, position, yaw), checked by `check_placement`; scale 1, the origin and yaw 0
    where it names none."""
    scale, position, yaw = msg.get("scale", 1.0), msg.get("position", [0, 0, 0]), msg.get("yaw", 0.0)
    if not isinstance(position, list) or len(position) != 3 or not all(type(v) in _NUMBER_TYPES for v in position):
        raise ProtocolError(f"position must be a list of 3 numbers, got {position!r}")
    for name, value in (("scale", scale), ("yaw", yaw)):
        if type(value) not in _NUMBER_TYPES:
            raise ProtocolError(f"{name} must be a number, got {value!r}")
    scale, _, yaw = check_placement(scale, position, yaw)
    return scale, position, yaw


def check_placement(scale, position, yaw) -> tuple[float, tuple, float]:
    """(scale, position, yaw) as floats when they lie in the scene's physical bounds (`SCALE_RANGE`, ±`ROOM`,
    ±`MAX_YAW`); else a ProtocolError naming the field."""
    try:
        scale, yaw, position = float(scale), float(yaw), tuple(float(v) for v in position)
    except (TypeError, ValueError, OverflowError):
        raise ProtocolError(f"a placement is numbers, got scale {scale!r}, position {position!r}, yaw {yaw!r}") \
            from None
    lo, hi = SCALE_RANGE
    if not lo <= scale <= hi:  # NaN fails too
        raise ProtocolError(f"scale must be within {lo:g}..{hi:g}, got {scale!r}")
    if len(position) != 3 or not all(abs(v) <= ROOM for v in position):
        raise ProtocolError(f"position must be 3 numbers within the room (±{ROOM:g} m), got {list(position)!r}")
    if not abs(yaw) <= MAX_YAW:
        raise ProtocolError(f"yaw must be within ±{MAX_YAW:.4g} radians (a full turn), got {yaw!r}")
    return scale, position, yaw


def check_hand(value) -> str | None:
    """A possessing hand from a client message: null, "left" or "right" (`motion.hands.SIDES`)."""
    if value is None or value in ("left", "right"):
        return value
    raise ProtocolError(f"hand must be null, \"left\" or \"right\", got {value!r}")


def check_subset(value) -> str | list | None:
    """A subset from a client message: null, a name, or a list of names."""
    if value is None or isinstance(value, str):
        return value or None
    if isinstance(value, list) and value and all(isinstance(v, str) for v in value):
        return value
    raise ProtocolError(f"subset must be null, a name or a list of names, got {value!r}")


# Users who send mocap rather than a camera's tracking: the server's sample player and VMC performers (a
# sender's own pipeline, often a suit or a tracker that filters already). The scene cleans camera users' frames
# before the solve and leaves these as sent unless asked (`kinetre studio --contact`).
SAMPLE_CLIENT = "sample"
VMC_CLIENT = "vmc"


def vmc_client(n: int) -> str:
    """The user name of the n-th VMC performer (1, 2, …)."""
    return f"{VMC_CLIENT}{n}"


def sends_mocap(client: str) -> bool:
    """Whether user `client` is the sample player or a VMC performer, not a page's camera (page clients are
    named `[xxxx-]c<n>[p<k>]`, so neither name can be a page's)."""
    return client == SAMPLE_CLIENT or (client.startswith(VMC_CLIENT) and client[len(VMC_CLIENT):].isdigit())


def person_client(client: str, person: int | None) -> str:
    """The user name of person `person` in `client`'s camera (no dots: it ends a channel subject)."""
    return client if person is None else f"{client}p{person}"


def is_person_of(user: str, client: str) -> bool:
    """Whether `user` is one of the people in `client`'s camera (see `person_client`)."""
    return user.startswith(client + "p") and user[len(client) + 1:].isdigit()


def skeleton_json(client: str, seq: int, t: float, skeleton: Skeleton, hands: np.ndarray | None = None,
                  blendshapes: np.ndarray | None = None) -> bytes:
    """The "skeleton" message forwarded to viewers (untracked rows become null), with the hands and
    blendshapes when given."""
    rows = [p if ok else None for p, ok in zip(np.round(skeleton.positions, 4).tolist(), skeleton.tracked)]
    msg = {"type": "skeleton", "client": client, "seq": seq, "t": t, "model": skeleton.model.name,
           "positions": rows, "tracked": skeleton.tracked.tolist()}
    if hands is not None:
        msg["hands"] = [h.tolist() if np.isfinite(h).all() else None for h in hands]
    if blendshapes is not None:
        msg["blendshapes"] = blendshapes.tolist()
    return json.dumps(msg).encode()


def with_client(text: str | bytes, client: str) -> bytes:
    """A validated client message (a JSON object) forwarded with the server's "client" key added last.

    Appending is much cheaper than re-encoding every frame, and JSON parsers keep the last of
    duplicate keys, so a client cannot pose as another.
    """
    raw = text.encode() if isinstance(text, str) else text
    return raw.rstrip()[:-1] + b', "client": "' + client.encode() + b'"}'
