"""Recorded takes as NDJSON (`.kinetre.jsonl`): a header line, then one JSON object per frame.

The format is documented in docs/take-format.md. Floats are written with Python's shortest repr, which
`json` reads back to the identical double, so replay is bit-exact for every tracked position.

    {"format": "kinetre-take", "version": 1, "model": "kinect20", "joints": [...], "parents": [...],
     "fps": 30.0, "source": "walk.bvh"}
    {"seq": 0, "t": 0.0, "positions": [[0.01, 0.93, 2.3], null, ...], "tracked": [true, false, ...]}
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from ..errors import BadMotionError, BadSkeletonError
from ..skeleton.models import MODELS, Skeleton, SkeletonModel
from .take import Take

FORMAT = "kinetre-take"
VERSION = 1


def header(model: SkeletonModel, fps: float, source: str = "") -> dict:
    """The first line of a take file, as a dict."""
    return {"format": FORMAT, "version": VERSION, "model": model.name, "joints": list(model.joints),
            "parents": list(model.parents), "fps": float(fps), "source": source}


def frame_record(seq: int, t: float, skeleton: Skeleton) -> dict:
    """One frame line as a dict: untracked joints have `null` positions."""
    pos = skeleton.positions.tolist()
    tracked = skeleton.tracked.tolist()
    return {"seq": int(seq), "t": float(t),
            "positions": [p if ok else None for p, ok in zip(pos, tracked)], "tracked": tracked}


class TakeWriter:
    """Write a take frame by frame (a camera recording stays a valid file if interrupted).

    >>> import io, kinetre
    >>> w = TakeWriter(io.StringIO(), kinetre.KINECT20, fps=30.0)
    >>> w.write(Skeleton.from_positions(kinetre.KINECT20, np.zeros((20, 3)))); w.frames
    1
    """

    def __init__(self, file, model: SkeletonModel, fps: float, source: str = ""):
        self.file = file
        self.model = model
        self.fps = float(fps)
        self.frames = 0
        self._line(header(model, fps, source))

    def _line(self, record: dict) -> None:
        self.file.write(json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n")

    def write(self, skeleton: Skeleton, t: float | None = None) -> None:
        """Append a frame; `t` defaults to frames / fps."""
        if skeleton.model != self.model:
            raise BadMotionError(f"take of {self.model.name!r}: got a {skeleton.model.name!r} frame")
        self._line(frame_record(self.frames, self.frames / self.fps if t is None else t, skeleton))
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
            writer = TakeWriter(f, take.model, take.fps, take.source if source is None else source)
            for i in range(len(take)):
                writer.write(take.frame(i))
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
    j = len(model.joints)
    positions = np.full((len(lines) - 1, j, 3), np.nan)
    tracked = np.zeros((len(lines) - 1, j), dtype=bool)
    last_seq = -1
    for k, (n, line) in enumerate(lines[1:]):
        rec = _json(path, n, line)
        seq, pos, ok = (rec.get(key) if isinstance(rec, dict) else None for key in ("seq", "positions", "tracked"))
        if not isinstance(seq, int) or seq <= last_seq:
            raise BadMotionError(f"{path}: line {n}: seq must be an integer above {last_seq}, got {seq!r}")
        last_seq = seq
        if not (isinstance(pos, list) and isinstance(ok, list) and len(pos) == j and len(ok) == j):
            raise BadMotionError(f"{path}: line {n}: expected {j} positions and {j} tracked flags")
        if not all(isinstance(b, bool) for b in ok):
            raise BadMotionError(f"{path}: line {n}: tracked must hold true/false values")
        for i, (p, b) in enumerate(zip(pos, ok)):
            if p is None:
                continue
            if not (isinstance(p, list) and len(p) == 3 and all(isinstance(c, (int, float)) for c in p)):
                raise BadMotionError(f"{path}: line {n}: joint {model.joints[i]!r} position must be [x, y, z] "
                                     f"or null, got {json.dumps(p)[:60]}")
            positions[k, i] = p
            tracked[k, i] = b
    if len(positions) == 0:
        raise BadMotionError(f"{path}: the take has a header but no frames")
    return Take(model, positions, tracked, float(fps), str(head.get("source") or path))


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
