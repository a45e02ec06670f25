"""Looking for small people: the whole image plus overlapping square crops, and merging what they find.

MediaPipe's detectors see a letterboxed square of the image at a low resolution (224 px for the body, 192 px
for hands), so in a wide frame a person a third of the height tall shrinks to a few dozen pixels and is
missed. Square crops as tall as the image's short side, overlapping by at least a third so anyone narrower
than the overlap lies whole inside one, show each person at up to twice that size. Every crop and the whole
image are searched; a person found in several is kept once (`distinct`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Tile:
    """A crop of the image: its top-left corner and size in pixels."""

    x: int
    y: int
    width: int
    height: int

    def to_image(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """(..., 2) coordinates normalised to this tile -> normalised to the whole (width, height) image."""
        p = np.asarray(points, dtype=np.float64)
        return np.stack([(self.x + p[..., 0] * self.width) / width, (self.y + p[..., 1] * self.height) / height],
                        axis=-1)


def square_tiles(width: int, height: int, overlap: float = 1 / 3) -> tuple[Tile, ...]:
    """The whole image, then (when it is not about square) squares of its short side along its long side,
    neighbours sharing at least `overlap` of a square, the first and last at the image's ends.

    >>> [(t.x, t.width) for t in square_tiles(640, 360)]
    [(0, 640), (0, 360), (140, 360), (280, 360)]
    """
    whole = Tile(0, 0, int(width), int(height))
    short, long = min(width, height), max(width, height)
    if long < 1.2 * short:
        return (whole,)
    count = math.ceil((long - short) / ((1 - overlap) * short)) + 1
    starts = np.round(np.linspace(0, long - short, count)).astype(int)
    if width >= height:
        return (whole,) + tuple(Tile(int(s), 0, short, short) for s in starts)
    return (whole,) + tuple(Tile(0, int(s), short, short) for s in starts)


def distinct(points: list[np.ndarray], scores: np.ndarray, same: float = 0.25) -> list[int]:
    """Indices of the detections to keep, best score first, dropping any that repeats a kept one.

    Two detections are the same thing when the median distance between their corresponding landmarks is
    below `same` times the larger one's size (its landmark box diagonal). The median ignores the few
    landmarks a crop's edge cut off and guessed, and people standing close together still differ in most.

    points : per detection (N, 2) landmarks in image pixels; scores : (len(points),) higher is better.
    """
    order = np.argsort(-np.asarray(scores, dtype=np.float64), kind="stable")
    kept: list[int] = []
    for i in order:
        a = points[i]
        size_a = _diagonal(a)
        if all(np.median(np.linalg.norm(a - points[k], axis=1)) >= same * max(size_a, _diagonal(points[k]))
               for k in kept):
            kept.append(int(i))
    return kept


def _diagonal(p: np.ndarray) -> float:
    return float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))
