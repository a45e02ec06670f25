"""Several people in one camera: a stable id per person across frames (track assignment with a short memory).

Each frame's detections are matched to the tracks seen in the last `memory` seconds by the assignment that
minimises the summed distance between body centres, measured in body sizes (the Hungarian method, as
`scipy.optimize.linear_sum_assignment` solves it). A detection farther than `gate` body sizes from every
free track starts a new id; a track unseen for longer than `memory` is forgotten, so someone who steps out
and back within that time keeps their id.

One of them is the main person (`main_person`): the one a camera's own channel follows (the studio page's
own user, a take's main skeleton). The page (web/src/app/People.ts) keeps the same rule.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Track:
    """A person seen before: id, body centre and size (image pixels) when last seen, that time and the time
    they were first seen (s)."""

    id: int
    center: tuple[float, float]
    size: float
    seen: float
    since: float


@dataclass(frozen=True)
class Tracks:
    """Everyone remembered, and the id the next new person gets."""

    tracks: tuple[Track, ...] = ()
    next_id: int = 0


def assign_ids(state: Tracks, centers: np.ndarray, sizes: np.ndarray, t: float,
               memory: float = 3.0, gate: float = 1.5) -> tuple[np.ndarray, Tracks]:
    """Ids for this frame's detections, and the updated memory.

    Parameters
    ----------
    state : the tracks before this frame
    centers : (M, 2) body centres of the detections (pixels); sizes : (M,) body sizes (pixels, > 0)
    t : this frame's time in seconds (not before the last frame's)
    memory : seconds a track is kept without being seen; gate : farthest match, in body sizes

    Returns
    -------
    ids : (M,) int64, distinct; the new state (matched tracks moved, new ones added, stale ones dropped)

    >>> ids, s = assign_ids(Tracks(), np.array([[0.0, 0.0], [100.0, 0.0]]), np.array([20.0, 20.0]), 0.0)
    >>> ids.tolist(), assign_ids(s, np.array([[98.0, 1.0]]), np.array([20.0]), 0.1)[0].tolist()
    ([0, 1], [1])
    """
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    sizes = np.asarray(sizes, dtype=np.float64).reshape(-1)
    live = [k for k in state.tracks if t - k.seen <= memory]
    ids = np.full(len(centers), -1, dtype=np.int64)
    if live and len(centers):
        from scipy.optimize import linear_sum_assignment
        old = np.array([k.center for k in live])
        scale = 0.5 * (sizes[:, None] + np.array([k.size for k in live])[None, :])
        cost = np.linalg.norm(centers[:, None, :] - old[None, :, :], axis=2) / np.maximum(scale, 1e-9)
        rows, cols = linear_sum_assignment(cost)
        for r, c in zip(rows, cols):
            if cost[r, c] <= gate:
                ids[r] = live[c].id
    next_id = state.next_id
    for r in np.flatnonzero(ids < 0):
        ids[r] = next_id
        next_id += 1
    since = {k.id: k.since for k in live}
    moved = {int(i): Track(int(i), (float(c[0]), float(c[1])), float(s), float(t), since.get(int(i), float(t)))
             for i, c, s in zip(ids, centers, sizes)}
    kept = [moved.pop(k.id, k) for k in live] + list(moved.values())
    return ids, Tracks(tuple(sorted(kept, key=lambda k: k.id)), next_id)


def main_person(main: int | None, state: Tracks, ids: np.ndarray, centers: np.ndarray,
                middle: tuple[float, float]) -> int | None:
    """The person a camera's own channel follows, after a frame's `assign_ids`.

    The main person keeps the role by id while remembered, even unseen for a moment, so a second person never
    takes it over because the landmarker missed the first in a frame or listed them in another order. It
    passes on when they are forgotten, or when someone first seen after they were last seen is in view (the
    tracker gave the main person a new id after a jump). It passes to the one of those in view nearest the
    frame's `middle` (the lowest id on a tie); None when the main person is forgotten and nobody is in view.

    Parameters
    ----------
    main : the main person before this frame (None at first)
    state : the tracks after this frame; ids, centers : this frame's ids and body centres (pixels)
    middle : the frame's centre (pixels)

    >>> ids, s = assign_ids(Tracks(), np.array([[100.0, 50.0], [330.0, 50.0]]), np.array([40.0, 40.0]), 0.0)
    >>> main_person(None, s, ids, np.array([[100.0, 50.0], [330.0, 50.0]]), (320.0, 180.0))
    1
    """
    ids = np.asarray(ids, dtype=np.int64).reshape(-1)
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    known = {k.id: k for k in state.tracks}
    if main in known:
        gone = known[main].seen
        newcomers = [k for k, i in enumerate(ids) if int(i) != main and known[int(i)].since > gone]
        if not newcomers:
            return main
    else:
        newcomers = list(range(len(ids)))
    if not newcomers:
        return None
    d = np.linalg.norm(centers[newcomers] - np.asarray(middle, dtype=np.float64), axis=1)
    return int(min(zip(d.tolist(), ids[newcomers].tolist()))[1])
