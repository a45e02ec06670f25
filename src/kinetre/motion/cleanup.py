"""Cleaning a tracked take so it looks right: smoothing without lag, feet held where they stand, jumps kept.

Offline (`clean_take`, the whole take known):

1. Smoothing: a One-Euro filter per joint with parameters from the take's own noise and speed
   (`filters.tune_one_euro`), run forwards then backwards so it adds no lag.
2. Contact: stance per contact joint and the floor, from the smoothed take (`contact.detect_stance`).
3. Foot locking: during each stance run the contact joint is held at the run's median point by two-bone IK on
   its leg, blending in before touch-down and out after lift-off over `blend` seconds; a contact joint
   below its resting level on the floor is lifted to it. Frames where every contact joint is off the floor
   (a jump) are left as smoothed.

Live (`LiveCleaner`, one frame at a time, no delay): a causal One-Euro filter tuned per joint from the last
seconds of frames, stance from backward speeds,
the floor from the stance points seen so far, and each stance held where it began.

What was applied (and its measured lag) is recorded in the take's `applied` header.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .contact import (NOMINAL_HEIGHT, Floor, Stance, StanceSettings, contact_joints, detect_stance, fit_floor,
                      joint_speed, place_contacts, runs)
from .filters import OneEuroFilter, one_euro_both_ways, tune_one_euro
from .quality import lag_ms
from .take import Take, camera_viewpoint


@dataclass(frozen=True)
class CleanupSettings:
    """smooth : the zero-lag One-Euro pass; contact : stance, floor and foot locking; blend : seconds over
    which a held joint lets go (and, offline, takes hold)."""

    smooth: bool = True
    contact: bool = True
    blend: float = 0.1
    stance: StanceSettings = StanceSettings()


def _holds(mask: np.ndarray, points: np.ndarray, airborne: np.ndarray, ramp: int
           ) -> tuple[np.ndarray, np.ndarray]:
    """(T,) weight and (T, 3) hold point of one contact joint: 1 on each stance run (held at its median),
    falling linearly to 0 over `ramp` frames either side, never on airborne frames."""
    t = len(mask)
    weight = np.zeros(t)
    hold = np.full((t, 3), np.nan)
    for a, b in runs(mask):
        seg = points[a:b]
        seg = seg[np.isfinite(seg).all(axis=1)]
        if not len(seg):
            continue
        at = np.median(seg, axis=0)
        lo, hi = max(0, a - ramp), min(t, b + ramp)
        idx = np.arange(lo, hi)
        w = np.ones(len(idx))
        w[idx < a] = 1 - (a - idx[idx < a]) / (ramp + 1)
        w[idx >= b] = 1 - (idx[idx >= b] - b + 1) / (ramp + 1)
        w[airborne[idx] & ~mask[idx]] = 0.0
        better = w > weight[idx]
        weight[idx[better]], hold[idx[better]] = w[better], at
    return weight, hold


def _fill(values: np.ndarray, known: np.ndarray) -> np.ndarray:
    """(T, D) values with the rows where `known` is False interpolated linearly in time between known rows
    (held at the ends); zeros when no row is known."""
    out = np.zeros_like(values)
    idx = np.flatnonzero(known)
    if not len(idx):
        return out
    for d in range(values.shape[1]):
        out[:, d] = np.interp(np.arange(len(values)), idx, values[idx, d])
    return out


def lock_contacts(model, positions: np.ndarray, fps: float, stance: Stance, blend: float,
                  bone_frames: np.ndarray | None = None, move_root: bool = False
                  ) -> tuple[np.ndarray, np.ndarray | None]:
    """Hold each contact joint of `stance` through its stance runs and lift it out of the floor (offline).

    With `move_root` (a camera take, whose depth and place wander as a whole) the body is first shifted
    horizontally so the held joints stay put, the shift interpolated across frames where nothing is held
    (a jump keeps its own shape); two-bone IK then holds each joint exactly."""
    pos = np.array(positions, dtype=np.float64)
    ramp = max(0, int(round(blend * fps)))
    airborne = stance.airborne()
    c_n = len(stance.joints)
    holds = [_holds(stance.mask[:, c], pos[:, j], airborne, ramp) for c, j in enumerate(stance.joints)]
    if move_root and c_n:
        w = np.stack([h[0] for h in holds], axis=1)                                     # (T, C)
        off = np.stack([h[1] - pos[:, j] for h, j in zip(holds, stance.joints)], axis=1)  # (T, C, 3)
        use = (w > 0) & np.isfinite(off).all(axis=2)
        ws = np.where(use, w, 0.0)
        total = ws.sum(axis=1)
        shift = (ws[..., None] * np.where(use[..., None], off, 0.0)).sum(axis=1) / np.maximum(total, 1e-12)[:, None]
        shift[:, 1] = 0.0
        pos += _fill(shift, total > 0)[:, None, :]
        holds = [_holds(stance.mask[:, c], pos[:, j], airborne, ramp) for c, j in enumerate(stance.joints)]
    targets = np.full((len(pos), c_n, 3), np.nan)
    weights = np.zeros((len(pos), c_n))
    for c, j in enumerate(stance.joints):
        w, hold = holds[c]
        p = pos[:, j]
        aim = np.where(w[:, None] > 0, p + w[:, None] * (hold - p), p)
        sink = stance.level[c] - stance.floor.above(aim)  # below its resting level: lift it
        aim[:, 1] += np.where(np.nan_to_num(sink) > 0, np.nan_to_num(sink), 0.0)
        moved = np.isfinite(aim).all(axis=1) & (np.abs(np.nan_to_num(aim - p)).max(axis=1) > 0)
        targets[:, c] = aim
        weights[moved, c] = 1.0
    return place_contacts(model, pos, targets, weights, stance.joints, bone_frames)


@dataclass(frozen=True)
class TrackResult:
    positions: np.ndarray
    bone_frames: np.ndarray | None
    stance: Stance | None
    record: dict


def clean_track(model, positions: np.ndarray, fps: float, settings: CleanupSettings = CleanupSettings(),
                bone_frames: np.ndarray | None = None, floor: Floor | None = None,
                viewpoint: np.ndarray | None = None) -> TrackResult:
    """Clean one person's (T, J, 3) joints offline; returns the new joints and a record of what was done.
    `viewpoint`: the camera's position for a camera take (its depth is the noisy direction)."""
    raw = np.asarray(positions, dtype=np.float64)
    pos, record = raw, {}
    if settings.smooth:
        tune = tune_one_euro(raw, fps)
        pos = one_euro_both_ways(raw, fps, tune.min_cutoff[:, None], tune.beta[:, None], tune.d_cutoff)
        pos = np.where(np.isfinite(raw), pos, np.nan)
        record["smoothing"] = {"filter": "one-euro", "pass": "forward-backward", "d_cutoff": tune.d_cutoff,
                               "lag_ms": _round(lag_ms(pos, raw, fps)),
                               "joints": tune.to_dict(model.joints)}
    stance = None
    if settings.contact:
        joints = contact_joints(model, pos)
        stance = detect_stance(pos, fps, joints, settings.stance, floor, viewpoint)
        pos, bone_frames = lock_contacts(model, pos, fps, stance, settings.blend, bone_frames,
                                         move_root=viewpoint is not None)
        record["contact"] = {"joints": [model.joints[j] for j in joints], "floor": stance.floor.to_dict(),
                             "blend_s": settings.blend,
                             "stance_frames": [int(s) for s in stance.mask.sum(axis=0)],
                             "airborne_frames": int(stance.airborne().sum())}
    return TrackResult(pos, bone_frames, stance, record)


def _round(x: float) -> float | None:
    return None if not np.isfinite(x) else round(float(x), 2)


def clean_take(take: Take, settings: CleanupSettings = CleanupSettings()) -> Take:
    """The take smoothed and with its contacts held (offline); every person of a camera take is cleaned,
    on one floor fitted to everyone's stance points. `applied` records what was done."""
    if not (settings.smooth or settings.contact):
        return take
    if not take.people:
        out = clean_track(take.model, take.positions, take.fps, settings, take.bone_frames,
                          viewpoint=camera_viewpoint(take))
        return replace(take, positions=out.positions, bone_frames=out.bone_frames,
                       applied={"offline": True, **out.record}, native=take.native)
    main = take.main_person()
    view = camera_viewpoint(take)
    floor = None
    if settings.contact:  # one floor for everyone in view: fit it to the first cleaning pass's stance points
        pts = []
        for k in range(len(take.people)):
            first = clean_track(take.model, take.crowd_positions[:, k], take.fps, settings, viewpoint=view)
            if first.stance is not None:
                for c, j in enumerate(first.stance.joints):
                    pts.append(first.positions[first.stance.mask[:, c], j])
        floor = fit_floor(np.concatenate(pts)) if pts and sum(map(len, pts)) else None
    crowd = take.crowd_positions.copy()
    record = {}
    for k in range(len(take.people)):
        out = clean_track(take.model, take.crowd_positions[:, k], take.fps, settings, floor=floor,
                          viewpoint=view)
        crowd[:, k] = np.where(take.crowd_tracked[:, k, :, None], out.positions, np.nan)
        record = record or out.record
    positions = take.positions.copy()
    seen = main >= 0
    positions[seen] = crowd[np.flatnonzero(seen), main[seen]]
    return replace(take, positions=positions, crowd_positions=crowd,
                   applied={"offline": True, "people": len(take.people), **record})


class RoomFloor:
    """One floor for everyone in a room: the stance points every user's `LiveCleaner` reports, the last
    `history` points kept, a plane fitted to them (`fit_floor`) once there are enough, and the resting
    `level` of the points above it (their 20th percentile). Both are refitted every 10 new points while
    there are few, then every tenth of the points kept, not per frame: a fit costs in proportion to its
    points, and a floor that rests on thousands of points moves little with the next ten, while its refit
    would cost the frame that triggers it more than the rest of its cleaning."""

    def __init__(self, history: int = 3000):
        self.history = history
        self._ring = np.empty((history, 3))
        self._count = 0  # points added so far; the ring holds the last min(count, history)
        self.floor: Floor | None = None
        self.level = 0.0
        self._fresh = 0

    def add(self, point: np.ndarray) -> None:
        self._ring[self._count % self.history] = point
        self._count += 1
        self._fresh += 1
        if self._count >= 10 and (self.floor is None or self._fresh >= max(10, min(self._count, self.history) // 10)):
            pts = self.points()
            self.floor, self._fresh = fit_floor(pts), 0
            self.level = resting_level(self.floor, pts)

    def points(self) -> np.ndarray:
        """The points kept, oldest first."""
        n = min(self._count, self.history)
        start = self._count % self.history if self._count > self.history else 0
        return np.roll(self._ring[:n], -start, axis=0)


def resting_level(floor: Floor, points: np.ndarray) -> float:
    """Where feet at rest stand above `floor`: the low end (20th percentile) of the stance points' heights
    (a foot is seen a little above the floor while it settles, and its heel or toe below)."""
    return float(np.percentile(floor.above(points), 20)) if len(points) else 0.0


class LiveCleaner:
    """Clean one person's joints frame by frame, causally, with no delay (a camera or the studio's live path).

    `viewpoint`: the camera's position when the joints come from one camera (its depth wanders): stance
    speeds are then taken across the line of sight, and while a foot is held the body is shifted
    horizontally so it stays put (the shift is kept through a jump and taken over by the next stance).
    `floor`: a known floor; `room`: a `RoomFloor` shared with the room's other users; else a floor is fitted
    to this person's stance points seen so far.

    >>> import kinetre
    >>> c = LiveCleaner(kinetre.KINECT20)
    >>> c(np.zeros((20, 3)), 0.0).shape
    (20, 3)
    """

    def __init__(self, model, settings: CleanupSettings = CleanupSettings(), min_cutoff: float = 1.0,
                 beta: float = 20.0, floor: Floor | None = None, history: float = 10.0,
                 viewpoint: np.ndarray | None = None, room: RoomFloor | None = None):
        self.model, self.settings = model, settings
        self.room = room
        self.filter = OneEuroFilter(min_cutoff, beta, 2.0)
        self.floor = floor
        self.fixed_floor = floor is not None
        self.history = history
        self.viewpoint = None if viewpoint is None else np.asarray(viewpoint, dtype=np.float64)
        self.joints: tuple[int, ...] | None = None
        self.shift = np.zeros(3)                   # horizontal shift of the whole body (camera sources)
        self._recent: list[np.ndarray] = []        # the last frames, as filtered (for backward speeds)
        self._times: list[float] = []
        self._stance_pts: list[np.ndarray] = []    # stance points seen, for the floor
        self._on: np.ndarray | None = None         # per contact joint: in stance now
        self._age: np.ndarray | None = None        # frames since it touched down
        self._hold: np.ndarray | None = None       # where each held joint is held
        self._weight: np.ndarray | None = None
        self._heights: list[float] = []
        self.tuning, self.retune = 3.0, 1.0      # seconds of frames the filter is tuned on, and how often
        self.ease = 0.25                         # seconds over which the body shift follows the held feet
        self.settle = 0.1                        # seconds of stance averaged into where a foot is held
        self._raw: list[np.ndarray] = []
        self._raw_t: list[float] = []
        self._tuned_at = -np.inf

    def __call__(self, positions: np.ndarray, t: float) -> np.ndarray:
        """The cleaned (J, 3) joints of a frame taken at `t` seconds (NaN rows stay NaN)."""
        raw = np.asarray(positions, dtype=np.float64)
        if self.settings.smooth:
            self._retune(raw, t)
        pos = self.filter(raw, t) if self.settings.smooth else raw.copy()
        if not self.settings.contact:
            return pos
        if self.joints is None:
            if not np.isfinite(raw).all(axis=1).sum() >= 2:
                return pos
            self.joints = contact_joints(self.model, raw[None])
            c = len(self.joints)
            self._on, self._weight, self._age = np.zeros(c, bool), np.zeros(c), np.zeros(c, int)
            self._hold = np.full((c, 3), np.nan)
        self._recent.append(pos)
        self._times.append(t)
        fps = self._fps()
        st = self.settings.stance
        del self._recent[:-(max(2, int(round(st.window * fps)) + 1))]
        del self._times[:-(max(2, int(round(st.window * fps)) + 1))]
        if np.isfinite(pos).all(axis=1).sum() >= 2:
            self._heights.append(float(np.nanmax(pos[:, 1]) - np.nanmin(pos[:, 1])))
            del self._heights[:-max(1, int(self.history * fps))]
        scale = (float(np.median(self._heights)) if self._heights else NOMINAL_HEIGHT) / NOMINAL_HEIGHT
        track = np.stack(self._recent)
        feet = pos[list(self.joints)]
        known = self.floor if self.fixed_floor or self.room is None else self.room.floor
        known = known if known is not None else self.floor
        floor = known or Floor(float(np.nanmin(feet[:, 1])) if np.isfinite(feet[:, 1]).any() else 0.0)
        # the resting level: the low end of the stance points on a fitted floor (the lower foot until then)
        if known is None:
            level = 0.0
        elif self.room is not None and self.room.floor is not None and known is self.room.floor:
            level = self.room.level
        else:
            pts = self.room.points() if self.room is not None and self.room.floor is not None else \
                np.array(self._stance_pts).reshape(-1, 3)
            level = resting_level(floor, pts)
        ramp = max(1, int(round(self.settings.blend * fps)))
        for c, j in enumerate(self.joints):
            p = pos[j]
            if not np.isfinite(p).all():
                self._on[c], self._weight[c] = False, 0.0
                continue
            speed = joint_speed(track[:, j], fps, st.window, causal=True, viewpoint=self.viewpoint)[-1]
            speed = np.inf if not np.isfinite(speed) else speed
            height = float(floor.above(p)) - level
            was = self._on[c]
            if was:
                # a held foot the tracker now sees well off its hold (the floor was not known yet when it
                # touched down) lets go, and is held again where it is
                off = abs(float(self._hold[c, 1] - p[1])) > st.height_off * scale
                self._on[c] = not (height > st.height_off * scale or speed > st.speed_off * scale or off)
                if off:
                    self._weight[c] = 0.0
            else:
                self._on[c] = height < st.height_on * scale and speed < st.speed_on * scale
            if self._on[c]:
                # back down while still letting go (a flicker of the tracker): the same hold, continued
                self._age[c] = self._age[c] + 1 if (was or self._weight[c] > 0) else 1
                # held at the mean of where it was seen over its first `settle` seconds down, with the body
                # shift so far: a foot put down again lands where the corrected body puts it
                n, here = self._age[c], p + self.shift
                if n <= self.settle * fps or not np.isfinite(self._hold[c]).all():
                    self._hold[c] = here if n == 1 or not np.isfinite(self._hold[c]).all() else \
                        self._hold[c] + (here - self._hold[c]) / n
                self._weight[c] = 1.0
                self._stance_pts.append(p.copy())
                del self._stance_pts[:-max(1, int(self.history * fps))]
                if self.room is not None:
                    self.room.add(p)
            else:
                self._age[c] = 0
                self._weight[c] = max(0.0, self._weight[c] - 1.0 / (ramp + 1))
        if not self._on.any():  # every contact off the floor (a jump): as tracked, the shift kept
            self._weight[:] = 0.0
        held = self._weight > 0
        if self.viewpoint is not None and held.any():
            w = self._weight[held]
            off = self._hold[held] - pos[list(np.array(self.joints)[held])]
            aim = (w[:, None] * off).sum(axis=0) / w.sum()
            aim[1] = 0.0
            # eased (`ease` seconds): the held foot stays put by IK anyway, and the body should not
            # take on the foot's tracking noise
            self.shift += (1.0 - np.exp(-1.0 / (self.ease * fps))) * (aim - self.shift)
        out = pos + self.shift
        targets = np.full((1, len(self.joints), 3), np.nan)
        weights = np.zeros((1, len(self.joints)))
        for c, j in enumerate(self.joints):
            if self._weight[c] > 0:
                targets[0, c] = out[j] + self._weight[c] * (self._hold[c] - out[j])
                weights[0, c] = 1.0
        # a room's floor is fitted by the room from everyone's stance points (this person's among them), and
        # is there before this person has ten of their own: a floor of their own would go unused
        if not self.fixed_floor and self.room is None and len(self._stance_pts) >= 10:
            self.floor = fit_floor(np.array(self._stance_pts))
        out, _ = place_contacts(self.model, out[None], targets, weights, self.joints)
        return out[0]

    def held(self) -> tuple[np.ndarray, np.ndarray]:
        """(C,) which contact joints are held now, and (C, 3) where (NaN where not)."""
        if self.joints is None:
            return np.zeros(0, bool), np.zeros((0, 3))
        on = self._weight >= 1.0
        return on, np.where(on[:, None], self._hold, np.nan)

    def _retune(self, raw: np.ndarray, t: float) -> None:
        """Every `retune` seconds, set the filter's parameters per joint from the last `tuning` seconds of
        tracked frames (their noise and speed, as offline); the given parameters until then."""
        self._raw.append(raw)
        self._raw_t.append(t)
        while self._raw_t and self._raw_t[0] < t - self.tuning:
            del self._raw[0], self._raw_t[0]
        if t - self._tuned_at < self.retune or t - self._raw_t[0] < 0.5 * self.tuning:
            return
        tune = tune_one_euro(np.stack(self._raw), self._fps_of(self._raw_t))
        self.filter.min_cutoff, self.filter.beta = tune.min_cutoff[:, None], tune.beta[:, None]
        self.filter.d_cutoff = tune.d_cutoff
        self._tuned_at = t

    def describe(self) -> dict:
        """What this cleaner applies, for a take's `applied` header."""
        out: dict = {"offline": False}
        if self.settings.smooth:
            out["smoothing"] = {"filter": "one-euro", "pass": "causal",
                                "tuning": f"per joint from the last {self.tuning:g} s of frames, every "
                                          f"{self.retune:g} s (min_cutoff {self.filter.min_cutoff} Hz, beta "
                                          f"{self.filter.beta} until then)"}
        if self.settings.contact:
            out["contact"] = {"blend_s": self.settings.blend, "floor": "fitted live to the stance points"}
        return out

    def _fps(self) -> float:
        return self._fps_of(self._times)

    @staticmethod
    def _fps_of(times: list[float]) -> float:
        if len(times) < 2:
            return 30.0
        dt = np.diff(times)
        dt = dt[dt > 0]
        return float(1.0 / np.median(dt)) if len(dt) else 30.0
