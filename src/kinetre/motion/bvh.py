"""BVH motion capture files: parse, forward kinematics over all frames, units, and the map to Kinect-20.

Reads any hierarchy (several roots, any joint names), any channel order, position channels on any joint
and End Sites. Conventions (those of Biovision, Blender and bvhio):

* a joint's local transform is  T(offset with position channels substituted) · R_c1 · R_c2 · R_c3,
  the rotations multiplied in the order the CHANNELS line lists them (Z Y X -> Rz Ry Rx), angles in degrees;
* the file is +Y up; its unit is unknown, so it is guessed from the skeleton's size (`detect_unit`);
* End Sites become joints named "<parent>_End" (they give the last bone of each chain its length).

Parsing is pure (`parse_bvh(text)`); `load_bvh(path)` reads the file and returns a `Take`.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np

from ..errors import BadMotionError
from ..rotation import axis_rotations, up_rotation
from ..skeleton.humanoid_map import kinect_frames, take_map
from ..skeleton.models import KINECT20, SkeletonModel
from .take import Take

_AXIS = {"x": 0, "y": 1, "z": 2}
_CHUNK = 4096  # frames per forward-kinematics batch
_CHANNELS = {f"{a}{kind}" for a in "xyz" for kind in ("position", "rotation")}


@dataclass(frozen=True, eq=False)
class BvhClip:
    """A parsed BVH file, before forward kinematics.

    Attributes
    ----------
    names : tuple of str, (J,)
        Joint names in file order (parents before children); End Sites are "<parent>_End".
    parents : tuple of int, (J,)
        Parent index per joint, -1 for a root.
    offsets : (J, 3) float64
        OFFSET of each joint from its parent, in file units.
    channels : tuple of tuple of str, (J,)
        Lower-case channel names per joint ("zrotation", "xposition", ...); End Sites have none.
    motion : (T, C) float64
        One row of channel values per frame, C = total channel count.
    frame_time : float
        Seconds per frame.
    source : str
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    motion: np.ndarray
    frame_time: float
    source: str = ""

    @property
    def end_sites(self) -> np.ndarray:
        """(J,) bool: True for End Site joints."""
        return np.array([n.endswith("_End") and not c for n, c in zip(self.names, self.channels)])

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time


class _Tokens:
    """Whitespace tokens of the hierarchy with their 1-based line numbers."""

    def __init__(self, lines: list[str], source: str):
        self.items = [(tok, n + 1) for n, line in enumerate(lines) for tok in line.split()]
        self.i = 0
        self.source = source
        self.last_line = len(lines)

    def peek(self) -> tuple[str | None, int]:
        return self.items[self.i] if self.i < len(self.items) else (None, self.last_line)

    def next(self, what: str) -> tuple[str, int]:
        tok, line = self.peek()
        if tok is None:
            self.fail(line, f"the hierarchy ends early (expected {what})")
        self.i += 1
        return tok, line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            self.fail(line, f"expected {what}, got {tok!r}")
        if not math.isfinite(value):
            self.fail(line, f"{what} is {tok!r}")
        return value

    def fail(self, line: int, message: str):
        raise BadMotionError(f"{self.source}: line {line}: {message}")


def parse_bvh(text: str, source: str = "<string>") -> BvhClip:
    """Parse BVH text into a `BvhClip` (no file access).

    Raises
    ------
    BadMotionError
        Naming `source` and the line: no HIERARCHY or MOTION, unbalanced braces, a bad OFFSET or
        CHANNELS line, an unknown channel, a frame row with the wrong number of values, fewer or more
        rows than `Frames:` declares, or a non-numeric value.
    """
    lines = text.splitlines()
    motion_at = next((n for n, line in enumerate(lines) if line.strip().upper() == "MOTION"), None)
    head = lines if motion_at is None else lines[:motion_at]
    tokens = _Tokens(head, source)
    tok, line = tokens.next("HIERARCHY")
    if tok.upper() != "HIERARCHY":
        tokens.fail(line, f"not a BVH file: expected HIERARCHY, got {tok[:40]!r}")

    names: list[str] = []
    parents: list[int] = []
    offsets: list[tuple[float, float, float] | None] = []
    channels: list[tuple[str, ...]] = []
    stack: list[int] = []
    while True:
        tok, line = tokens.peek()
        if tok is None:
            break
        tokens.i += 1
        key = tok.upper()
        if key in ("ROOT", "JOINT") or (key == "END" and tokens.peek()[0] in ("Site", "SITE", "site")):
            if key == "ROOT" and stack:
                tokens.fail(line, "ROOT inside another joint (missing '}')")
            if key != "ROOT" and not stack:
                tokens.fail(line, f"{tok} outside any ROOT")
            if key == "END":
                tokens.i += 1
                name = f"{names[stack[-1]]}_End"
            else:
                parts = []
                while tokens.peek()[0] not in (None, "{") and tokens.peek()[1] == line:
                    parts.append(tokens.next("a name")[0])
                if not parts:
                    tokens.fail(line, f"{tok} without a name")
                name = " ".join(parts)
            brace, bline = tokens.next("'{'")
            if brace != "{":
                tokens.fail(bline, f"expected '{{' after {tok} {name}, got {brace!r}")
            base, k = name, 2
            while name in names:  # keep names unique (a SkeletonModel needs them to be)
                name, k = f"{base}.{k}", k + 1
            names.append(name)
            parents.append(stack[-1] if stack else -1)
            offsets.append(None)
            channels.append(())
            stack.append(len(names) - 1)
        elif key == "OFFSET":
            if not stack:
                tokens.fail(line, "OFFSET outside any joint")
            offsets[stack[-1]] = tuple(tokens.number(f"OFFSET {a}") for a in "xyz")
        elif key == "CHANNELS":
            if not stack:
                tokens.fail(line, "CHANNELS outside any joint")
            count = tokens.number("the channel count")
            if count != int(count) or not 0 <= count <= 6:
                tokens.fail(line, f"channel count must be 0..6, got {count:g}")
            names_here = []
            for _ in range(int(count)):
                c, cline = tokens.next("a channel name")
                if c.lower() not in _CHANNELS:
                    tokens.fail(cline, f"CHANNELS {int(count)} lists {len(names_here)} channel(s), then "
                                       f"{c!r} (expected Xposition .. Zrotation)")
                names_here.append(c.lower())
            if len(set(names_here)) != len(names_here):
                tokens.fail(line, f"repeated channel in {' '.join(names_here)}")
            channels[stack[-1]] = tuple(names_here)
        elif key == "}":
            if not stack:
                tokens.fail(line, "unbalanced '}'")
            j = stack.pop()
            if offsets[j] is None:
                tokens.fail(line, f"joint {names[j]!r} has no OFFSET")
        else:
            tokens.fail(line, f"unexpected {tok[:40]!r} in the hierarchy")
    if stack:
        tokens.fail(tokens.last_line, f"joint {names[stack[-1]]!r} is not closed with '}}'")
    if not names:
        tokens.fail(tokens.last_line, "no ROOT joint in the hierarchy")
    if motion_at is None:
        raise BadMotionError(f"{source}: no MOTION section (the file ends after the hierarchy, "
                             f"line {len(lines)})")

    n_channels = sum(len(c) for c in channels)
    frames, frame_time, rows = _parse_motion(lines, motion_at, n_channels, source)
    return BvhClip(tuple(names), tuple(parents), np.array(offsets, dtype=np.float64), tuple(channels),
                   rows, frame_time, source)


def _header_value(lines, n, label, source):
    if n >= len(lines):
        raise BadMotionError(f"{source}: line {n + 1}: the file ends before '{label}'")
    m = re.fullmatch(rf"\s*{label}\s*(\S+)\s*", lines[n], flags=re.IGNORECASE)
    if not m:
        raise BadMotionError(f"{source}: line {n + 1}: expected '{label} <number>', got {lines[n].strip()[:60]!r}")
    return m.group(1)


def _parse_motion(lines, motion_at, n_channels, source):
    n = motion_at + 1
    while n < len(lines) and not lines[n].strip():
        n += 1
    frames_text = _header_value(lines, n, "Frames:", source)
    if not frames_text.isdigit():
        raise BadMotionError(f"{source}: line {n + 1}: Frames: must be a whole number, got {frames_text!r}")
    frames = int(frames_text)
    time_text = _header_value(lines, n + 1, "Frame Time:", source)
    try:
        frame_time = float(time_text)
    except ValueError:
        frame_time = float("nan")
    if not (math.isfinite(frame_time) and frame_time > 0):
        raise BadMotionError(f"{source}: line {n + 2}: Frame Time: must be a positive number, got {time_text!r}")
    if frames == 0:
        raise BadMotionError(f"{source}: line {n + 1}: Frames: 0, the file holds no motion")
    first = n + 2
    numbered = [(k + 1, line) for k, line in enumerate(lines[first:], start=first) if line.strip()]
    for lineno, line in numbered:
        got = len(line.split())
        if got != n_channels:
            raise BadMotionError(f"{source}: line {lineno}: expected {n_channels} channel values "
                                 f"(the hierarchy's CHANNELS), got {got}")
    if len(numbered) < frames:
        raise BadMotionError(f"{source}: truncated: Frames: says {frames} but only {len(numbered)} rows follow "
                             f"(file ends at line {len(lines)})")
    if len(numbered) > frames:
        raise BadMotionError(f"{source}: line {numbered[frames][0]}: Frames: says {frames} but "
                             f"{len(numbered)} rows follow")
    try:
        rows = np.array(" ".join(line for _, line in numbered).split(), dtype=np.float64)
    except ValueError:
        for lineno, line in numbered:
            for tok in line.split():
                try:
                    float(tok)
                except ValueError:
                    raise BadMotionError(f"{source}: line {lineno}: {tok[:40]!r} is not a number") from None
        raise
    rows = rows.reshape(frames, n_channels)
    if not np.isfinite(rows).all():
        bad = int(np.argwhere(~np.isfinite(rows))[0, 0])
        raise BadMotionError(f"{source}: line {numbered[bad][0]}: non-finite channel value")
    return frames, frame_time, rows


def forward_kinematics(clip: BvhClip, frames: slice | None = None) -> np.ndarray:
    """World positions (T, J, 3) float64 of every joint (End Sites included) in file units."""
    return joint_frames(clip, frames)[0]


def joint_frames(clip: BvhClip, frames: slice | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World positions (T, J, 3) in file units and rotations (T, J, 3, 3) of every joint (End Sites
    included).

    Vectorised over frames: one pass over the joints, each a batch of 3x3 products.
    """
    motion = clip.motion if frames is None else clip.motion[frames]
    t = motion.shape[0]
    j_count = len(clip.names)
    pos = np.zeros((t, j_count, 3))
    rot = np.zeros((t, j_count, 3, 3))
    col = 0
    for j, (parent, channels) in enumerate(zip(clip.parents, clip.channels)):
        local_t = np.repeat(clip.offsets[j][None], t, axis=0)
        local_r = None
        for k, name in enumerate(channels):
            values = motion[:, col + k]
            if name.endswith("position"):
                local_t[:, _AXIS[name[0]]] = values
            else:
                r = axis_rotations(_AXIS[name[0]], values)
                local_r = r if local_r is None else local_r @ r
        col += len(channels)
        if local_r is None:
            local_r = np.broadcast_to(np.eye(3), (t, 3, 3))
        if parent < 0:
            pos[:, j] = local_t
            rot[:, j] = local_r
        else:
            pos[:, j] = pos[:, parent] + np.einsum("tab,tb->ta", rot[:, parent], local_t)
            rot[:, j] = rot[:, parent] @ local_r
    return pos, rot


def rest_positions(clip: BvhClip) -> np.ndarray:
    """(J, 3) positions of the hierarchy from OFFSETs alone (no channels), in file units."""
    pos = np.zeros((len(clip.names), 3))
    for j, p in enumerate(clip.parents):
        pos[j] = clip.offsets[j] + (pos[p] if p >= 0 else 0.0)
    return pos


# Candidate units, metres per file unit; the one that makes the skeleton the most plausible size wins.
# "cmu" is the unit of the CMU database's ASF/AMC and its BVH conversions: inch / 0.45 (":units length 0.45").
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": 0.0254 / 0.45}
HUMAN_HEIGHT = 1.7  # metres: the size a file in an unknown unit is guessed to have


def detect_unit(size: float) -> tuple[float, str]:
    """Guess metres per file unit from the skeleton's size (its rest-pose extent, file units).

    Picks the unit of `UNITS` whose result is nearest 1.7 m (in log scale) if that lands within
    1.0–2.3 m; otherwise (custom units, e.g. the CMU conversions) scales the skeleton to 1.7 m.

    >>> detect_unit(175.0)
    (0.01, 'cm')
    >>> detect_unit(68.0)
    (0.0254, 'inch')
    >>> detect_unit(3.0)
    (0.5666666666666667, 'normalised to 1.7 m')
    """
    if not (math.isfinite(size) and size > 0):
        return 1.0, "m"
    name, per = min(UNITS.items(), key=lambda kv: abs(math.log(size * kv[1] / HUMAN_HEIGHT)))
    if 1.0 <= size * per <= 2.3:
        return per, name
    return HUMAN_HEIGHT / size, f"normalised to {HUMAN_HEIGHT} m"


def kinect_map(names: tuple[str, ...], parents: tuple[int, ...],
               rest: np.ndarray | None = None) -> tuple[np.ndarray, dict] | None:
    """The linear map from a hierarchy's joints to Kinect-20 (`kinetre.skeleton.humanoid_map`), or None
    when the skeleton is not a humanoid.

    Parameters
    ----------
    rest : (J, 3) float, optional
        Rest positions (topology's and geometry's evidence, the upright check); without them names and
        topology alone decide.

    Returns
    -------
    weights : (20, J) float64
        Kinect positions = weights @ file positions (a selection, or a blend for derived joints); rows of
        joints that do not map are zero.
    drivers : dict
        Kinect joint -> the file joint(s) it comes from (for `kinetre info`).
    """
    hmap = take_map(names, parents, rest)
    return None if hmap is None else (hmap.weights(), hmap.drivers())


def load_bvh(path: str | os.PathLike, scale: float | None = None, as_kinect: bool = True) -> Take:
    """Read a BVH file as a `Take` in metres, +Y up.

    Parameters
    ----------
    path : str or PathLike
    scale : float, optional
        Metres per file unit; by default guessed from the skeleton's size (`detect_unit`).
    as_kinect : bool
        Map a humanoid skeleton to Kinect-20 (`kinetre.skeleton.humanoid_map`: names, topology, rest-pose
        geometry; Kinect joints it lacks are derived or untracked); otherwise, or when False, keep the
        file's own hierarchy (End Sites included) as a generic SkeletonModel named "bvh:<file stem>" (an
        animal drives the mesh by its own bones).

    Notes
    -----
    A human skeleton (mapped to Kinect-20) whose rest pose stands along another axis (a Z-up file) is
    turned to +Y up by the quarter turn that takes its hips->head axis to +Y; other skeletons are taken
    as +Y up, as BVH specifies.

    Raises
    ------
    BadMotionError
        Missing or unreadable file, or any parse error (with the line).
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read()
    except FileNotFoundError:
        raise BadMotionError(f"{path}: no such file") from None
    except (IsADirectoryError, PermissionError, OSError) as e:
        raise BadMotionError(f"{path}: cannot read ({e.strerror or e})") from None
    clip = parse_bvh(text, source=path)
    if scale is None:
        scale, _ = detect_unit(float(np.ptp(rest_positions(clip), axis=0).max()))
    elif not (math.isfinite(scale) and scale > 0):
        raise BadMotionError(f"{path}: scale must be a positive number, got {scale!r}")
    # in chunks of frames: the per-joint world rotations of a long clip would not fit in memory at once
    chunks = [joint_frames(clip, slice(i, i + _CHUNK)) for i in range(0, len(clip.motion), _CHUNK)]
    positions = np.concatenate([c[0] for c in chunks]) * scale
    stem = os.path.basename(path).rsplit(".", 1)[0]
    model = SkeletonModel(f"bvh:{stem}", clip.names, clip.parents)
    own = Take(model, positions, np.ones(positions.shape[:2], dtype=bool), clip.fps, path,
               bone_frames=carried_by(np.concatenate([c[1] for c in chunks]), clip.parents))
    rest = rest_positions(clip) * scale
    hmap = take_map(clip.names, clip.parents, rest) if as_kinect else None
    if hmap is None:
        return own
    return kinect_take(hmap, own, upright(hmap, rest))


def upright(hmap, rest: np.ndarray) -> np.ndarray:
    """(3, 3) the quarter turn taking a mapped human's rest hips -> head (else shoulder centre) to +Y."""
    kinect, _ = kinect_frames(hmap, rest)
    top = "Head" if "Head" in hmap.joints else "ShoulderCenter"
    return up_rotation(kinect[KINECT20.index(top)] - kinect[KINECT20.index("HipCenter")])


def carried_by(rotations: np.ndarray, parents) -> np.ndarray:
    """(T, J, 3, 3) per joint its parent's world rotation (a root: its own) from every joint's (T, J, 3, 3):
    the frame of the bone that carries the joint."""
    p = np.asarray(parents)
    return rotations[:, np.where(p >= 0, p, np.arange(len(p)))]


def kinect_take(hmap, own: Take, turn: np.ndarray, native: Take | None = None) -> Take:
    """A file's own take as Kinect-20 through `hmap`, turned by `turn` (its up to +Y). A Kinect joint taken
    from one source joint keeps the bone frame that carries it; a derived or missing one has none (NaN).
    The own take (or `native`, the file's skeleton as a take drives with it) rides along as `native`."""
    positions, tracked = kinect_frames(hmap, own.positions[:, :len(hmap.names)])
    bone_frames = None
    if own.bone_frames is not None:
        bone_frames = np.full(positions.shape + (3,), np.nan)
        for k, name in enumerate(KINECT20.joints):
            if name in hmap.joints:
                bone_frames[:, k] = turn @ own.bone_frames[:, hmap.joints[name]]
    return Take(KINECT20, positions @ turn.T, tracked, own.fps, own.source, bone_frames=bone_frames,
                native=own if native is None else native)
