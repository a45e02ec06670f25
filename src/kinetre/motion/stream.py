"""Recorded takes as NDJSON (`.kinetre.jsonl`): a header line, then one JSON object per frame.

The format is documented in docs/take-format.md. Floats are written with Python's shortest repr, which
`json` reads back to the identical double, so replay is bit-exact for every tracked position.

    {"format": "kinetre-take", "version": 1, "model": "kinect20", "joints": [...], "parents": [...],
     "fps": 30.0, "source": "walk.bvh"}
    {"seq": 0, "t": 0.0, "positions": [[0.01, 0.93, 2.3], null, ...], "tracked": [true, false, ...]}

Camera takes may add, per frame, `"people"`: everyone seen with their id, joints, hands and face blendshapes
(the header then names the blendshapes); readers of the one-person fields are unaffected.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import BadMotionError, BadSkeletonError
from ..skeleton.models import MODELS, Skeleton, SkeletonModel
from .take import PersonFrame, Take, crowd_take

FORMAT = "kinetre-take"
VERSION = 1


def header(model: SkeletonModel, fps: float, source: str = "", blendshape_names: tuple[str, ...] = (),
           applied: dict | None = None) -> dict:
    """The first line of a take file, as a dict."""
    head = {"format": FORMAT, "version": VERSION, "model": model.name, "joints": list(model.joints),
            "parents": list(model.parents), "fps": float(fps), "source": source}
    if blendshape_names:
        head["blendshapes"] = list(blendshape_names)
    if applied is not None:
        head["applied"] = applied
    return head


def _joints(skeleton: Skeleton) -> dict:
    pos = skeleton.positions.tolist()
    tracked = skeleton.tracked.tolist()
    return {"positions": [p if ok else None for p, ok in zip(pos, tracked)], "tracked": tracked}


def _points(a: np.ndarray | None):
    """Rows with a NaN become null; a wholly missing array stays null."""
    if a is None or not np.isfinite(a).any():
        return None
    return [p if np.isfinite(p).all() else None for p in a.tolist()]


def person_record(person: PersonFrame) -> dict:
    rec = {"id": int(person.id), **_joints(person.skeleton)}
    if person.hands is not None and np.isfinite(person.hands).any():
        rec["hands"] = [_points(h) if np.isfinite(h).all() else None for h in person.hands]
    if person.blendshapes is not None and np.isfinite(person.blendshapes).all():
        rec["blendshapes"] = person.blendshapes.tolist()
    return rec


def frame_record(seq: int, t: float, skeleton: Skeleton, people: tuple[PersonFrame, ...] | None = None) -> dict:
    """One frame line as a dict: untracked joints have `null` positions; `people` adds everyone seen."""
    rec = {"seq": int(seq), "t": float(t), **_joints(skeleton)}
    if people is not None:
        rec["people"] = [person_record(p) for p in people]
    return rec


def _people_at(take: Take, i: int) -> tuple[PersonFrame, ...] | None:
    if not take.people:
        return None
    out = []
    for k, pid in enumerate(take.people):
        hands = None if take.hands is None else take.hands[i, k]
        face = None if take.blendshapes is None else take.blendshapes[i, k]
        seen = take.crowd_tracked[i, k].any() or (hands is not None and np.isfinite(hands).any()) \
            or (face is not None and np.isfinite(face).all())
        if seen:
            out.append(PersonFrame(pid, Skeleton(take.model, take.crowd_positions[i, k], take.crowd_tracked[i, k]),
                                   hands, face))
    return tuple(out)


class TakeWriter:
    """Write a take frame by frame (a camera recording stays a valid file if interrupted).

    >>> import io, kinetre
    >>> w = TakeWriter(io.StringIO(), kinetre.KINECT20, fps=30.0)
    >>> w.write(Skeleton.from_positions(kinetre.KINECT20, np.zeros((20, 3)))); w.frames
    1
    """

    def __init__(self, file, model: SkeletonModel, fps: float, source: str = "",
                 blendshape_names: tuple[str, ...] = (), applied: dict | None = None):
        self.file = file
        self.model = model
        self.fps = float(fps)
        self.frames = 0
        self.blendshapes = len(blendshape_names)
        self._line(header(model, fps, source, blendshape_names, applied))

    def _line(self, record: dict) -> None:
        self.file.write(json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n")

    def write(self, skeleton: Skeleton, t: float | None = None, people: tuple[PersonFrame, ...] | None = None) -> None:
        """Append a frame (with everyone seen in it, when given); `t` defaults to frames / fps."""
        for model in [skeleton.model] + [p.skeleton.model for p in people or ()]:
            if model != self.model:
                raise BadMotionError(f"take of {self.model.name!r}: got a {model.name!r} frame")
        if any(p.blendshapes is not None and len(p.blendshapes) != self.blendshapes for p in people or ()):
            raise BadMotionError(f"take with {self.blendshapes} blendshapes: got a face with another count")
        self._line(frame_record(self.frames, self.frames / self.fps if t is None else t, skeleton, people))
        self.frames += 1
        self.file.flush()


def write_stream(path: str | os.PathLike, take: Take | list[Skeleton], fps: float | None = None,
                 source: str | None = None) -> None:
    """Write a `Take` (or a list of Skeleton frames with their `fps`) to a `.kinetre.jsonl` file."""
    if not isinstance(take, Take):
        if fps is None:
            raise BadMotionError(f"{path}: writing a list of frames needs their fps")
        take = Take.from_frames(list(take), fps, source or "")
    try:
        with open(path, "w", encoding="utf-8") as f:
            writer = TakeWriter(f, take.model, take.fps, take.source if source is None else source,
                                take.blendshape_names, take.applied)
            for i in range(len(take)):
                writer.write(take.frame(i), people=_people_at(take, i))
    except OSError as e:
        raise BadMotionError(f"{path}: cannot write ({e.strerror or e})") from None


def read_stream(path: str | os.PathLike) -> Take:
    """Read a `.kinetre.jsonl` take.

    Raises
    ------
    BadMotionError
        Naming the file and line: not JSON, not a kinetre take, an unknown version, a frame whose
        positions or tracked mask do not match the joints, sequence numbers that go backwards, no frames.
    """
    path = os.fspath(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise BadMotionError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise BadMotionError(f"{path}: cannot read ({getattr(e, 'strerror', None) or e})") from None
    lines = [(n + 1, line) for n, line in enumerate(text.splitlines()) if line.strip()]
    if not lines:
        raise BadMotionError(f"{path}: empty file, expected a kinetre-take header line")
    head = _json(path, *lines[0])
    if not isinstance(head, dict) or head.get("format") != FORMAT:
        raise BadMotionError(f"{path}: line {lines[0][0]}: not a kinetre take (expected a header with "
                             f"\"format\": \"{FORMAT}\")")
    if head.get("version") != VERSION:
        raise BadMotionError(f"{path}: unsupported take version {head.get('version')!r} (this reader: {VERSION})")
    model = _model(path, head)
    fps = head.get("fps")
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise BadMotionError(f"{path}: line {lines[0][0]}: fps must be a positive number, got {fps!r}")
    names = head.get("blendshapes", [])
    if not (isinstance(names, list) and all(isinstance(x, str) for x in names)):
        raise BadMotionError(f"{path}: line {lines[0][0]}: blendshapes must be a list of names")
    applied = head.get("applied")
    if applied is not None and not isinstance(applied, dict):
        raise BadMotionError(f"{path}: line {lines[0][0]}: applied must be an object")
    j = len(model.joints)
    crowd: list[tuple[PersonFrame, ...]] = []
    positions = np.full((len(lines) - 1, j, 3), np.nan)
    tracked = np.zeros((len(lines) - 1, j), dtype=bool)
    last_seq = -1
    for k, (n, line) in enumerate(lines[1:]):
        rec = _json(path, n, line)
        seq, pos, ok = (rec.get(key) if isinstance(rec, dict) else None for key in ("seq", "positions", "tracked"))
        if not isinstance(seq, int) or seq <= last_seq:
            raise BadMotionError(f"{path}: line {n}: seq must be an integer above {last_seq}, got {seq!r}")
        last_seq = seq
        positions[k], tracked[k] = _read_joints(path, n, model, pos, ok)
        people = rec.get("people")
        if people is not None:
            if not isinstance(people, list):
                raise BadMotionError(f"{path}: line {n}: people must be a list")
            crowd.append(tuple(_read_person(path, n, model, p, len(names)) for p in people))
        else:
            crowd.append(())
    if len(positions) == 0:
        raise BadMotionError(f"{path}: the take has a header but no frames")
    source = str(head.get("source") or path)
    if not any(crowd):
        return Take(model, positions, tracked, float(fps), source, applied=applied)
    main = [Skeleton(model, positions[k], tracked[k]) for k in range(len(positions))]
    try:
        return replace(crowd_take(main, crowd, float(fps), source, tuple(names)), applied=applied)
    except BadMotionError as e:
        raise BadMotionError(f"{path}: {e}") from None


def _read_joints(path, n, model: SkeletonModel, pos, ok) -> tuple[np.ndarray, np.ndarray]:
    j = len(model.joints)
    if not (isinstance(pos, list) and isinstance(ok, list) and len(pos) == j and len(ok) == j):
        raise BadMotionError(f"{path}: line {n}: expected {j} positions and {j} tracked flags")
    if not all(isinstance(b, bool) for b in ok):
        raise BadMotionError(f"{path}: line {n}: tracked must hold true/false values")
    positions = np.full((j, 3), np.nan)
    for i, p in enumerate(pos):
        if p is None:
            continue
        if not _xyz(p):
            raise BadMotionError(f"{path}: line {n}: joint {model.joints[i]!r} position must be [x, y, z] "
                                 f"or null, got {json.dumps(p)[:60]}")
        positions[i] = p
    return positions, np.array(ok, dtype=bool)


def _xyz(p) -> bool:
    return isinstance(p, list) and len(p) == 3 and all(isinstance(c, (int, float)) and not isinstance(c, bool)
                                                       for c in p)


def _read_person(path, n, model: SkeletonModel, rec, blendshapes: int) -> PersonFrame:
    if not (isinstance(rec, dict) and isinstance(rec.get("id"), int) and not isinstance(rec.get("id"), bool)):
        raise BadMotionError(f"{path}: line {n}: each person needs an integer id")
    pos, ok = _read_joints(path, n, model, rec.get("positions"), rec.get("tracked"))
    hands = None
    if rec.get("hands") is not None:
        h = rec["hands"]
        if not (isinstance(h, list) and len(h) == 2):
            raise BadMotionError(f"{path}: line {n}: person {rec['id']}: hands must be [left, right]")
        hands = np.full((2, 21, 3), np.nan)
        for side, marks in enumerate(h):
            if marks is None:
                continue
            if not (isinstance(marks, list) and len(marks) == 21 and all(_xyz(p) for p in marks)):
                raise BadMotionError(f"{path}: line {n}: person {rec['id']}: a hand must be 21 [x, y, z] or null")
            hands[side] = marks
    face = None
    if rec.get("blendshapes") is not None:
        b = rec["blendshapes"]
        if not (isinstance(b, list) and len(b) == blendshapes
                and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in b)):
            raise BadMotionError(f"{path}: line {n}: person {rec['id']}: blendshapes must be {blendshapes} "
                                 f"numbers (the header's names)")
        face = np.array(b, dtype=np.float64)
    return PersonFrame(rec["id"], Skeleton(model, pos, ok), hands, face)


def _json(path, n, line):
    try:
        return json.loads(line)
    except json.JSONDecodeError as e:
        raise BadMotionError(f"{path}: line {n}: not JSON ({e.msg} at column {e.colno})") from None


def _model(path, head: dict) -> SkeletonModel:
    name, joints, parents = head.get("model"), head.get("joints"), head.get("parents")
    if not (isinstance(name, str) and isinstance(joints, list) and isinstance(parents, list)
            and all(isinstance(x, str) for x in joints) and all(isinstance(x, int) for x in parents)):
        raise BadMotionError(f"{path}: the header needs model (a name), joints (names) and parents (integers)")
    known = MODELS.get(name)
    if known is not None and (list(known.joints) != joints or list(known.parents) != parents):
        raise BadMotionError(f"{path}: model {name!r} with joints or parents other than the built-in ones")
    try:
        return known or SkeletonModel(name, tuple(joints), tuple(parents))
    except BadSkeletonError as e:  # e.g. a parent index out of range
        raise BadMotionError(f"{path}: {e}") from None
