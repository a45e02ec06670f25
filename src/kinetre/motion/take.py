"""`Take`: a whole clip of skeleton frames in one canonical frame (metres, +Y up, with a tracked mask).

Every motion reader (BVH, recorded stream, video, glTF animation) returns one; `source.load_take` picks
the reader. The class lives apart from the dispatcher so readers and dispatcher do not import each other.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import BadMotionError
from ..skeleton.models import Skeleton, SkeletonModel


@dataclass(frozen=True, eq=False)
class Take:
    """A clip of skeleton frames.

    Attributes
    ----------
    model : SkeletonModel
        The joint hierarchy (Kinect-20 for humans, the file's own for animals and custom rigs).
    positions : (T, J, 3) float64
        Joint positions in metres, +Y up; rows of untracked joints may be NaN.
    tracked : (T, J) bool
        False where the joint was not tracked; non-finite positions are always untracked.
    fps : float
        Frames per second (frame i is at time i / fps).
    source : str
        Where the take came from (a path, "camera 0", ...).
    people : tuple of int
        Camera takes: the ids of everyone tracked (`positions` is one of them, the main person);
        empty for a one-person take.
    crowd_positions : (T, P, J, 3) float64 or None; crowd_tracked : (T, P, J) bool or None
        Every person's joints, in the order of `people` (NaN / False where that person is not seen).
    hands : (T, P, 2, 21, 3) float64 or None
        MediaPipe's 21 hand landmarks of each person's left and right hand, in the take's frame
        (metres, +Y up, the wrist at the body's wrist); NaN where the hand is not found.
    blendshapes : (T, P, B) float64 or None; blendshape_names : tuple of B str
        Face blendshape weights in [0, 1] (MediaPipe's ARKit-named set); NaN where the face is not found.
    bone_frames : (T, J, 3, 3) float64 or None
        Per joint, the world rotation of the bone that carries it (its parent joint's frame, twist included)
        where the source has joint rotations (BVH, glTF); NaN where a joint has none; None for
        position-only sources (a camera).
    applied : dict or None
        What cleaned the take after tracking (smoothing, contact; `kinetre.motion.cleanup`), as written in the
        take file's header; None for a take as its source gave it.
    hips_turns : (T, 3, 3) float64 or None
        A VRM Animation's hips rotation from its rest T-pose (VRM's frame: facing +Z, +Y up), in the take's
        frame: the humanoid's root turn as its author posed it, which a torso frame fitted to the joints only
        approximates. None for other sources.
    native : Take or None
        A take mapped to Kinect-20 from a file's own skeleton: that skeleton as the file has it (its joints,
        units and frame, before the mapping's turn), so a source that already lies inside a mesh can drive
        it with all its bones where it stands.

    Examples
    --------
    >>> import kinetre
    >>> t = Take(kinetre.KINECT20, np.zeros((3, 20, 3)), np.ones((3, 20), bool), 20.0)
    >>> len(t), t.frame(2).positions.shape, t.duration
    (3, (20, 3), 0.1)
    """

    model: SkeletonModel
    positions: np.ndarray
    tracked: np.ndarray
    fps: float
    source: str = ""
    people: tuple[int, ...] = ()
    crowd_positions: np.ndarray | None = None
    crowd_tracked: np.ndarray | None = None
    hands: np.ndarray | None = None
    blendshapes: np.ndarray | None = None
    blendshape_names: tuple[str, ...] = ()
    bone_frames: np.ndarray | None = None
    native: "Take | None" = None
    applied: dict | None = None
    hips_turns: np.ndarray | None = None

    def __post_init__(self):
        pos = np.asarray(self.positions, dtype=np.float64)
        j = len(self.model.joints)
        where = self.source or "take"
        if pos.ndim != 3 or pos.shape[1:] != (j, 3):
            raise BadMotionError(f"{where}: positions must be (T, {j}, 3), got {pos.shape}")
        if pos.shape[0] == 0:
            raise BadMotionError(f"{where}: the take has no frames")
        tracked = np.asarray(self.tracked, dtype=bool)
        if tracked.shape != pos.shape[:2]:
            raise BadMotionError(f"{where}: tracked must be {pos.shape[:2]}, got {tracked.shape}")
        if not (isinstance(self.fps, (int, float)) and math.isfinite(self.fps) and self.fps > 0):
            raise BadMotionError(f"{where}: fps must be a positive number, got {self.fps!r}")
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "tracked", tracked & np.isfinite(pos).all(axis=2))
        object.__setattr__(self, "fps", float(self.fps))
        self._check_people(where, pos.shape[0], j)
        if self.bone_frames is not None:
            rot = np.asarray(self.bone_frames, dtype=np.float64)
            if rot.shape != pos.shape + (3,):
                raise BadMotionError(f"{where}: bone_frames must be {pos.shape + (3,)}, got {rot.shape}")
            object.__setattr__(self, "bone_frames", rot)
        if self.hips_turns is not None:
            turns = np.asarray(self.hips_turns, dtype=np.float64)
            if turns.shape != (pos.shape[0], 3, 3):
                raise BadMotionError(f"{where}: hips_turns must be {(pos.shape[0], 3, 3)}, got {turns.shape}")
            object.__setattr__(self, "hips_turns", turns)
        if self.native is not None and len(self.native) != pos.shape[0]:
            raise BadMotionError(f"{where}: the native take has {len(self.native)} frames, not {pos.shape[0]}")

    def _check_people(self, where: str, t: int, j: int) -> None:
        p = len(self.people)
        object.__setattr__(self, "people", tuple(int(i) for i in self.people))
        object.__setattr__(self, "blendshape_names", tuple(self.blendshape_names))
        if len(set(self.people)) != p:
            raise BadMotionError(f"{where}: person ids must be distinct, got {list(self.people)}")
        shapes = {"crowd_positions": (t, p, j, 3), "crowd_tracked": (t, p, j), "hands": (t, p, 2, 21, 3),
                  "blendshapes": (t, p, len(self.blendshape_names))}
        for name, shape in shapes.items():
            value = getattr(self, name)
            if value is None:
                if p and name.startswith("crowd"):
                    raise BadMotionError(f"{where}: a take with people needs {name}")
                continue
            if not p:
                raise BadMotionError(f"{where}: {name} given without person ids")
            value = np.asarray(value, dtype=bool if name == "crowd_tracked" else np.float64)
            if value.shape != shape:
                raise BadMotionError(f"{where}: {name} must be {shape}, got {value.shape}")
            object.__setattr__(self, name, value)
        if p:
            object.__setattr__(self, "crowd_tracked",
                               self.crowd_tracked & np.isfinite(self.crowd_positions).all(axis=3))

    def _extras(self, s=slice(None), points=None, turn=None) -> dict:
        """The people fields and bone frames, frames `s`, with `points` applied to every position array and
        `turn` (a rotation) to the bone frames."""
        move = points or (lambda x: x)
        pick = lambda x: None if x is None else x[s]  # noqa: E731
        rot = None if self.bone_frames is None else self.bone_frames[s]
        hips = None if self.hips_turns is None else self.hips_turns[s]
        if rot is not None and turn is not None:
            rot = turn @ rot
        if hips is not None and turn is not None:
            hips = turn @ hips @ turn.T
        return {"bone_frames": rot, "hips_turns": hips, "people": self.people,
                "crowd_positions": None if self.crowd_positions is None else move(self.crowd_positions[s]),
                "crowd_tracked": pick(self.crowd_tracked),
                "hands": None if self.hands is None else move(self.hands[s]),
                "blendshapes": pick(self.blendshapes), "blendshape_names": self.blendshape_names,
                "applied": self.applied}

    def person(self, pid: int) -> "Take":
        """Person `pid` alone (their joints, hands and face) as a one-person take."""
        if not self.people:
            raise BadMotionError(f"{self.source or 'take'}: records no people by id (not a camera take), so there "
                                 f"is no person {pid}")
        if pid not in self.people:
            raise BadMotionError(f"{self.source or 'take'}: no person {pid} (the take has {list(self.people)})")
        k = self.people.index(pid)
        one = slice(k, k + 1)
        return Take(self.model, self.crowd_positions[:, k], self.crowd_tracked[:, k], self.fps, self.source,
                    (pid,), self.crowd_positions[:, one], self.crowd_tracked[:, one],
                    None if self.hands is None else self.hands[:, one],
                    None if self.blendshapes is None else self.blendshapes[:, one], self.blendshape_names,
                    applied=self.applied)

    def split_people(self) -> list["Take"]:
        """Everyone as a one-person take, by increasing id (the take itself when it records no people)."""
        return [self.person(pid) for pid in sorted(self.people)] if self.people else [self]

    def main_person(self) -> np.ndarray:
        """(T,) per frame the index in `people` of the person whose joints are the frame's own (the main
        person), -1 where none is (no people, or nobody tracked)."""
        out = np.full(len(self), -1, dtype=np.int64)
        if not self.people:
            return out
        same = (self.crowd_tracked == self.tracked[:, None]).all(axis=2) & self.tracked.any(axis=1)[:, None]
        main = np.where(self.tracked[:, None, :, None], self.positions[:, None], 0.0)
        crowd = np.where(self.crowd_tracked[..., None], self.crowd_positions, 0.0)
        same &= (main == crowd).all(axis=(2, 3))
        hit = same.any(axis=1)
        out[hit] = np.argmax(same[hit], axis=1)
        return out

    def main_hands(self) -> np.ndarray | None:
        """(T, 2, 21, 3) the main person's hands (NaN where not seen), or None when the take has no hands."""
        if self.hands is None:
            return None
        k = self.main_person()
        out = np.full((len(self), 2, 21, 3), np.nan)
        out[k >= 0] = self.hands[np.flatnonzero(k >= 0), k[k >= 0]]
        return out

    def main_blendshapes(self) -> np.ndarray | None:
        """(T, B) the main person's blendshapes (NaN where not seen), or None when the take has no faces."""
        if self.blendshapes is None:
            return None
        k = self.main_person()
        out = np.full((len(self), len(self.blendshape_names)), np.nan)
        out[k >= 0] = self.blendshapes[np.flatnonzero(k >= 0), k[k >= 0]]
        return out

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return (len(self) - 1) / self.fps

    def frame(self, i: int) -> Skeleton:
        """Frame i as a `Skeleton` (negative i counts from the end)."""
        n = len(self)
        if not -n <= i < n:
            raise BadMotionError(f"{self.source or 'take'}: frame {i} out of range (the take has {n} frames)")
        return Skeleton(self.model, self.positions[i], self.tracked[i],
                        None if self.bone_frames is None else self.bone_frames[i])

    def frames(self) -> list[Skeleton]:
        return [self.frame(i) for i in range(len(self))]

    def slice(self, start: int = 0, stop: int | None = None, step: int = 1) -> "Take":
        """Frames start:stop:step (fps divided by step); at least one frame must remain."""
        s = slice(start, stop, step)
        if not self.positions[s].shape[0]:
            raise BadMotionError(f"{self.source or 'take'}: frames {start}:{stop} select nothing "
                                 f"(the take has {len(self)} frames)")
        return Take(self.model, self.positions[s], self.tracked[s], self.fps / step, self.source,
                    native=None if self.native is None else self.native.slice(start, stop, step), **self._extras(s))

    def transformed(self, scale: float = 1.0, rotation=None, translation=(0.0, 0.0, 0.0)) -> "Take":
        """Every frame under x -> scale * rotation @ x + translation."""
        r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        t = np.asarray(translation, dtype=np.float64)
        move = lambda x: scale * x @ r.T + t  # noqa: E731
        return Take(self.model, move(self.positions), self.tracked, self.fps, self.source,
                    native=None if self.native is None else self.native.transformed(scale, r, t),
                    **self._extras(points=move, turn=r))

    @staticmethod
    def from_frames(frames: list[Skeleton], fps: float, source: str = "") -> "Take":
        """Stack skeleton frames (all of one model) into a take."""
        if not frames:
            raise BadMotionError(f"{source or 'take'}: no frames")
        model = frames[0].model
        if any(f.model != model for f in frames):
            raise BadMotionError(f"{source or 'take'}: frames mix skeleton models")
        framed = all(f.bone_frames is not None for f in frames)
        return Take(model, np.stack([f.positions for f in frames]), np.stack([f.tracked for f in frames]),
                    fps, source, bone_frames=np.stack([f.bone_frames for f in frames]) if framed else None)


_CAMERA_EXTS = (".mp4", ".mov", ".avi", ".mkv", ".webm")


def is_camera_take(take: Take) -> bool:
    """Whether a take was tracked from images (a video or a camera): positions only, with people or a camera
    or video source."""
    src = take.source.lower()
    return take.bone_frames is None and (bool(take.people) or src.startswith("camera") or src.endswith(_CAMERA_EXTS))


def camera_viewpoint(take: Take) -> np.ndarray | None:
    """Where the camera of a camera take is (its origin, docs/take-format.md); None for other takes."""
    return np.zeros(3) if is_camera_take(take) else None


@dataclass(frozen=True, eq=False)
class PersonFrame:
    """One person in one camera frame: their id, joints, hands and face.

    skeleton : the person's joints; hands : (2, 21, 3) left and right hand landmarks (NaN rows where a hand
    is not found) or None; blendshapes : (B,) face blendshape weights or None when no face is found.
    """

    id: int
    skeleton: Skeleton
    hands: np.ndarray | None = None
    blendshapes: np.ndarray | None = None


def crowd_take(main: list[Skeleton], people: list[tuple[PersonFrame, ...]], fps: float, source: str = "",
               blendshape_names: tuple[str, ...] = ()) -> Take:
    """A take from per-frame main skeletons and everyone seen in each frame (ids in order of appearance)."""
    base = Take.from_frames(main, fps, source)
    ids = list(dict.fromkeys(p.id for frame in people for p in frame))
    if not ids:
        return base
    t, j = base.positions.shape[:2]
    pos = np.full((t, len(ids), j, 3), np.nan)
    tracked = np.zeros((t, len(ids), j), dtype=bool)
    hands = np.full((t, len(ids), 2, 21, 3), np.nan)
    faces = np.full((t, len(ids), len(blendshape_names)), np.nan)
    any_hands = any_face = False
    for i, frame in enumerate(people):
        for p in frame:
            k = ids.index(p.id)
            pos[i, k], tracked[i, k] = p.skeleton.positions, p.skeleton.tracked
            if p.hands is not None:
                hands[i, k], any_hands = p.hands, True
            if p.blendshapes is not None and blendshape_names:
                faces[i, k], any_face = p.blendshapes, True
    return Take(base.model, base.positions, base.tracked, base.fps, base.source, tuple(ids), pos, tracked,
                hands if any_hands else None, faces if any_face else None,
                blendshape_names if any_face else ())
