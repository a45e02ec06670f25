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
        return Skeleton(self.model, self.positions[i], self.tracked[i])

    def frames(self) -> list[Skeleton]:
        return [self.frame(i) for i in range(len(self))]

    def slice(self, start: int = 0, stop: int | None = None, step: int = 1) -> "Take":
        """Frames start:stop:step (fps divided by step); at least one frame must remain."""
        s = slice(start, stop, step)
        if not self.positions[s].shape[0]:
            raise BadMotionError(f"{self.source or 'take'}: frames {start}:{stop} select nothing "
                                 f"(the take has {len(self)} frames)")
        return Take(self.model, self.positions[s], self.tracked[s], self.fps / step, self.source)

    def transformed(self, scale: float = 1.0, rotation=None, translation=(0.0, 0.0, 0.0)) -> "Take":
        """Every frame under x -> scale * rotation @ x + translation."""
        r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        pos = scale * self.positions @ r.T + np.asarray(translation, dtype=np.float64)
        return Take(self.model, pos, self.tracked, self.fps, self.source)

    @staticmethod
    def from_frames(frames: list[Skeleton], fps: float, source: str = "") -> "Take":
        """Stack skeleton frames (all of one model) into a take."""
        if not frames:
            raise BadMotionError(f"{source or 'take'}: no frames")
        model = frames[0].model
        if any(f.model != model for f in frames):
            raise BadMotionError(f"{source or 'take'}: frames mix skeleton models")
        return Take(model, np.stack([f.positions for f in frames]), np.stack([f.tracked for f in frames]),
                    fps, source)
