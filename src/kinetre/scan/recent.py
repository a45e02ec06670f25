"""What tracking derives from a frame, kept for the last few frames of one scan.

Each frame is the source of one frame-to-frame step and the target of the next, and its ORB features serve
loop closure too: `RecentFrames` lets each of these be made once per frame. It is owned by whoever runs the
scan (`fuse_sequence`) and passed down; without one, everything is computed afresh. Frames are recognised by
the identity of their arrays, which are not modified while a scan holds them.
"""
from __future__ import annotations

from typing import Callable, TypeVar

import numpy as np

T = TypeVar("T")


class RecentFrames:
    """A small most-recent-first memo of per-frame results, keyed by (kind, arrays..., options...)."""

    def __init__(self, size: int = 8):
        self.size = size
        self._entries: list[tuple[tuple, object]] = []

    @staticmethod
    def _same(a: tuple, b: tuple) -> bool:
        return len(a) == len(b) and all(x is y if isinstance(x, np.ndarray) else x == y for x, y in zip(a, b))

    def get(self, key: tuple, make: Callable[[], T]) -> T:
        """The result stored under `key`, or `make()` stored under it (dropping the oldest beyond `size`)."""
        for stored, value in self._entries:
            if self._same(stored, key):
                return value
        value = make()
        self._entries.insert(0, (key, value))
        del self._entries[self.size:]
        return value


def remembered(recent: RecentFrames | None, key: tuple, make: Callable[[], T]) -> T:
    """`make()`, through `recent` when a scan keeps one."""
    return make() if recent is None else recent.get(key, make)
