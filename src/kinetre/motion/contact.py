"""Contact with the floor: which joints touch it, where the floor is, when each contact joint is in stance,
and holding a stance joint where it stands by two-bone IK on its leg.

Stance uses two cues with hysteresis (a joint enters stance low and slow, and leaves it only when clearly
high or fast), so noise near a threshold does not flicker. The floor is a plane fitted robustly to the
stance points. Heights and speeds scale with the body's height, so a child, a dog or a chair's legs use the
same rules as an adult.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..skeleton.models import SkeletonModel

# Named contact joints of the built-in bodies; other skeletons use their lowest leaves.
_NAMED = {"kinect20": ("FootLeft", "FootRight"), "openni17": ("LeftFoot", "RightFoot")}
NOMINAL_HEIGHT = 1.7  # metres: the thresholds below are for a body this tall and scale with it


@dataclass(frozen=True)
class StanceSettings:
    """Stance thresholds for a body NOMINAL_HEIGHT tall (scaled by the body's height).

    height_on / height_off : metres above the joint's own resting level to enter / leave stance
    speed_on / speed_off : metres per second to enter / leave stance
    window : seconds over which a joint's speed is measured (a central difference, or a backward one live)
    min_frames : shorter stance runs are dropped (a foot passing slowly at the bottom of its swing)
    """

    height_on: float = 0.05
    height_off: float = 0.09
    speed_on: float = 0.35
    speed_off: float = 0.7
    window: float = 0.1
    min_frames: int = 3


@dataclass(frozen=True)
class Floor:
    """The floor plane y = slope[0] * x + slope[1] * z + height, metres, +Y up."""

    height: float
    slope: tuple[float, float] = (0.0, 0.0)

    def above(self, points: np.ndarray) -> np.ndarray:
        """Height of points (..., 3) above the floor, along +Y."""
        p = np.asarray(points, dtype=np.float64)
        return p[..., 1] - (self.slope[0] * p[..., 0] + self.slope[1] * p[..., 2] + self.height)

    def to_dict(self) -> dict:
        return {"height": float(self.height), "slope": [float(s) for s in self.slope]}


def contact_joints(model: SkeletonModel, positions: np.ndarray) -> tuple[int, ...]:
    """The joints that touch the floor: the feet of a known body, else the leaves whose median height is
    within a tenth of the body's height of the lowest leaf's (a quadruped's hooves, a chair's legs)."""
    named = _NAMED.get(model.name)
    if named:
        return tuple(model.index(n) for n in named)
    parents = np.asarray(model.parents)
    leaves = [j for j in range(len(model.joints)) if j not in set(parents.tolist())]
    pos = np.asarray(positions, dtype=np.float64)
    with np.errstate(all="ignore"):
        level = np.array([np.nanmedian(pos[:, j, 1]) if np.isfinite(pos[:, j, 1]).any() else np.inf
                          for j in leaves])
    if not np.isfinite(level).any():
        return ()
    low = level[np.isfinite(level)].min()
    return tuple(j for j, y in zip(leaves, level) if y <= low + 0.1 * body_height(pos))


def leg_chain(model: SkeletonModel, contact: int) -> tuple[int, int, int] | None:
    """(root, mid, end) of the two-bone leg that places contact joint `contact`: a leaf (a toe, a hoof tip) is
    carried rigidly by its parent, so the leg ends at that parent (hip, knee, ankle for a human foot)."""
    parents = model.parents
    end = contact if contact in parents else parents[contact]
    if end < 0:
        return None
    mid = parents[end]
    root = parents[mid] if mid >= 0 else -1
    return (root, mid, end) if root >= 0 else None


def body_height(positions: np.ndarray) -> float:
    """Median over frames of the tracked joints' vertical extent (1.7 m when nothing is tracked)."""
    y = np.asarray(positions, dtype=np.float64)[..., 1]
    ok = np.isfinite(y).sum(axis=1) >= 2
    if not ok.any():
        return NOMINAL_HEIGHT
    h = float(np.median(np.nanmax(y[ok], axis=1) - np.nanmin(y[ok], axis=1)))
    return h if h > 1e-6 else NOMINAL_HEIGHT


def joint_speed(points: np.ndarray, fps: float, window: float, causal: bool = False,
                viewpoint: np.ndarray | None = None) -> np.ndarray:
    """(T,) speed of one joint's (T, 3) track: displacement across `window` seconds (central, or backward
    when `causal`), NaN where the track is missing. With a `viewpoint` (a single camera's position) motion
    along the line of sight is left out: a monocular tracker's depth wanders far more than its image does."""
    p = np.asarray(points, dtype=np.float64)
    t = len(p)
    k = max(1, int(round(window * fps / (1 if causal else 2))))
    idx = np.arange(t)
    a = np.maximum(0, idx - k)
    b = idx if causal else np.minimum(t - 1, idx + k)
    d = p[b] - p[a]
    if viewpoint is not None:
        ray = p - np.asarray(viewpoint, dtype=np.float64)
        ray /= np.maximum(np.linalg.norm(ray, axis=1), 1e-9)[:, None]
        d = d - (d * ray).sum(axis=1, keepdims=True) * ray
    with np.errstate(invalid="ignore"):
        out = np.linalg.norm(d, axis=1) * fps / np.maximum(b - a, 1)
    out[(b <= a) | ~np.isfinite(out)] = np.nan
    return out


def fit_floor(points: np.ndarray, spread: float = 0.5) -> Floor:
    """A floor plane through (N, 3) stance points, robust to outliers (iteratively reweighted least squares
    with Tukey's biweight). The tilt is fitted only where the points spread over `spread` metres
    horizontally; a person standing in place gives a level floor at their feet."""
    p = np.asarray(points, dtype=np.float64)
    p = p[np.isfinite(p).all(axis=1)]
    if not len(p):
        return Floor(0.0)
    flat = float(np.median(p[:, 1]))
    xz = p[:, [0, 2]]
    if np.ptp(xz, axis=0).max() < spread or len(p) < 10:
        return Floor(flat)
    a = np.column_stack([xz - xz.mean(axis=0), np.ones(len(p))])
    w = np.ones(len(p))
    coef = np.zeros(3)
    for _ in range(10):
        # the normal equations of the weighted fit: three unknowns, and the columns (centred, and ones) are
        # well conditioned, so this is lstsq's answer at a fraction of its cost (the live path refits often)
        aw = a * (w * w)[:, None]
        coef, before = np.linalg.solve(aw.T @ a + 1e-12 * np.eye(3), aw.T @ p[:, 1]), coef
        if np.abs(coef - before).max() < 1e-7:  # settled to a tenth of a micrometre
            break
        r = p[:, 1] - a @ coef
        s = 4.685 * max(1.4826 * np.median(np.abs(r)), 1e-3)
        w = np.clip(1 - (r / s) ** 2, 0, None)  # sqrt of the biweight (1 - u^2)^2: rows scale by it
    sx, sz = float(coef[0]), float(coef[1])
    if np.hypot(sx, sz) > 0.25:  # steeper than ~14 degrees is a bad fit, not a floor
        return Floor(flat)
    return Floor(float(coef[2] - sx * xz[:, 0].mean() - sz * xz[:, 1].mean()), (sx, sz))


def hysteresis(low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """(T,) bool: on from a frame where `low` holds until a frame where `high` holds (NaN-free bool inputs)."""
    out = np.zeros(len(low), dtype=bool)
    on = False
    for i in range(len(low)):
        on = (not high[i]) if on else bool(low[i])
        out[i] = on
    return out


def drop_short(mask: np.ndarray, frames: int) -> np.ndarray:
    """`mask` without its runs of True shorter than `frames`."""
    out = mask.copy()
    for a, b in runs(mask):
        if b - a < frames:
            out[a:b] = False
    return out


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in a (T,) bool array."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


@dataclass(frozen=True)
class Stance:
    """Contact of a take: `joints` (C,) contact joint indices, `mask` (T, C) in stance, the `floor`, and each
    joint's resting `level` (C,) above it."""

    joints: tuple[int, ...]
    mask: np.ndarray
    floor: Floor
    level: np.ndarray

    def airborne(self) -> np.ndarray:
        """(T,) frames where no contact joint is in stance (a jump)."""
        return ~self.mask.any(axis=1) if self.mask.shape[1] else np.zeros(len(self.mask), bool)


def detect_stance(positions: np.ndarray, fps: float, joints: tuple[int, ...],
                  settings: StanceSettings = StanceSettings(), floor: Floor | None = None,
                  viewpoint: np.ndarray | None = None) -> Stance:
    """Stance of each contact joint over a whole take (offline: speeds look both ways; with a camera's
    `viewpoint`, speeds across the line of sight).

    Slow frames are stance candidates; the floor is fitted to them (unless given), the joints' resting level
    is the low end of the candidates' heights above it, and stance is then low and slow, with hysteresis."""
    pos = np.asarray(positions, dtype=np.float64)
    t = len(pos)
    scale = body_height(pos) / NOMINAL_HEIGHT
    if not joints:
        return Stance((), np.zeros((t, 0), bool), floor or Floor(0.0), np.zeros(0))
    speed = np.stack([joint_speed(pos[:, j], fps, settings.window, viewpoint=viewpoint) for j in joints], axis=1)
    slow = np.nan_to_num(speed, nan=np.inf) < settings.speed_on * scale
    if floor is None:
        pts = np.concatenate([pos[slow[:, c], j] for c, j in enumerate(joints)]) if slow.any() else \
            pos[:, list(joints)].reshape(-1, 3)
        floor = fit_floor(pts)
    height = floor.above(pos[:, list(joints)])  # (T, C)
    # one resting level for every contact joint: the low end of the candidates (a foot held up while the
    # other stands is slow too, and must not pull the floor up to it)
    cand = height[slow & np.isfinite(height)]
    if not len(cand):
        cand = height[np.isfinite(height)]
    level = np.full(len(joints), float(np.percentile(cand, 20)) if len(cand) else 0.0)
    rel = np.nan_to_num(height - level, nan=np.inf)
    spd = np.nan_to_num(speed, nan=np.inf)
    mask = np.zeros((t, len(joints)), dtype=bool)
    for c in range(len(joints)):
        low = (rel[:, c] < settings.height_on * scale) & (spd[:, c] < settings.speed_on * scale)
        high = (rel[:, c] > settings.height_off * scale) | (spd[:, c] > settings.speed_off * scale)
        mask[:, c] = drop_short(hysteresis(low, high), settings.min_frames)
    return Stance(tuple(joints), mask, floor, level)


def two_bone_ik(root: np.ndarray, mid: np.ndarray, end: np.ndarray, target: np.ndarray, stretch: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray]:
    """New (mid, end) (N, 3) placing `end` at `target` with both bone lengths kept and the joint bent in the
    plane it bends in now (the knee keeps pointing where it pointed). A target beyond the straight leg
    lengthens both bones by up to `stretch` (a fraction: a tracker's bone lengths vary by more); one still
    out of reach is approached along the line to it."""
    a = np.linalg.norm(mid - root, axis=-1)
    b = np.linalg.norm(end - mid, axis=-1)
    to = target - root
    if stretch > 0:
        grow = np.clip(np.linalg.norm(to, axis=-1) / np.maximum(a + b, 1e-12), 1.0, 1.0 + stretch)
        a, b = a * grow, b * grow
    d = np.linalg.norm(to, axis=-1)
    d_ok = np.clip(d, np.abs(a - b) + 1e-9, a + b - 1e-9)
    u = to / np.maximum(d, 1e-12)[..., None]
    # the bend plane: where the mid joint stands off the old root-to-end line, kept off the new one
    old = end - root
    old = old / np.maximum(np.linalg.norm(old, axis=-1), 1e-12)[..., None]
    bend = (mid - root) - ((mid - root) * old).sum(-1, keepdims=True) * old
    perp = bend - (bend * u).sum(-1, keepdims=True) * u
    n = np.linalg.norm(perp, axis=-1)
    # a straight leg has no bend plane of its own: keep the old bend's direction, or any direction across
    fallback = np.cross(u, np.array([1.0, 0.0, 0.0]))
    perp = np.where((n > 1e-6 * np.maximum(a, 1e-9))[..., None], perp, fallback)
    perp /= np.maximum(np.linalg.norm(perp, axis=-1), 1e-12)[..., None]
    cos = np.clip((a ** 2 + d_ok ** 2 - b ** 2) / (2 * np.maximum(a * d_ok, 1e-12)), -1.0, 1.0)
    sin = np.sqrt(1 - cos ** 2)
    new_mid = root + a[..., None] * (cos[..., None] * u + sin[..., None] * perp)
    new_end = root + d_ok[..., None] * u
    return new_mid, new_end


def descendants(model: SkeletonModel, joint: int) -> list[int]:
    """`joint` and every joint below it."""
    out, todo = [], [joint]
    while todo:
        j = todo.pop()
        out.append(j)
        todo += [c for c, p in enumerate(model.parents) if p == j]
    return out


def _turn(old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """(N, 3, 3) the least rotations taking directions `old` to `new` (N, 3)."""
    u = old / np.maximum(np.linalg.norm(old, axis=-1), 1e-12)[..., None]
    v = new / np.maximum(np.linalg.norm(new, axis=-1), 1e-12)[..., None]
    axis = np.cross(u, v)
    s = np.linalg.norm(axis, axis=-1)
    c = (u * v).sum(-1)
    k = axis / np.maximum(s, 1e-12)[..., None]
    kx = np.zeros(u.shape[:-1] + (3, 3))
    kx[..., 0, 1], kx[..., 0, 2], kx[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    kx = kx - np.swapaxes(kx, -1, -2)
    eye = np.broadcast_to(np.eye(3), kx.shape)
    return eye + s[..., None, None] * kx + (1 - c)[..., None, None] * (kx @ kx)


def place_contacts(model: SkeletonModel, positions: np.ndarray, targets: np.ndarray, weights: np.ndarray,
                   joints: tuple[int, ...], bone_frames: np.ndarray | None = None, stretch: float = 0.03
                   ) -> tuple[np.ndarray, np.ndarray | None]:
    """Move each contact joint `joints[c]` a fraction `weights` (T, C) of the way to `targets` (T, C, 3) by
    two-bone IK on its leg; the leg's end carries its children rigidly. Returns new positions (and the bone
    frames of the two turned bones turned with them). Frames with weight 0 are returned untouched. A leg
    may stretch by `stretch` to reach."""
    pos = np.array(positions, dtype=np.float64)
    frames = None if bone_frames is None else np.array(bone_frames, dtype=np.float64)
    for c, j in enumerate(joints):
        chain = leg_chain(model, j)
        w = np.nan_to_num(weights[:, c])
        rows = np.flatnonzero((w > 0) & np.isfinite(targets[:, c]).all(axis=1) & np.isfinite(pos[:, j]).all(axis=1))
        if chain is None or not len(rows):
            continue
        r, m, e = chain
        rows = rows[np.isfinite(pos[rows][:, [r, m, e]]).all(axis=(1, 2))]
        if not len(rows):
            continue
        shift = w[rows, None] * (targets[rows, c] - pos[rows, j])
        old_m, old_e = pos[rows, m].copy(), pos[rows, e].copy()
        new_m, new_e = two_bone_ik(pos[rows, r], old_m, old_e, old_e + shift, stretch)
        if frames is not None:
            for bone, (a0, b0, a1, b1) in ((m, (pos[rows, r], old_m, pos[rows, r], new_m)),
                                           (e, (old_m, old_e, new_m, new_e))):
                turn = _turn(b0 - a0, b1 - a1)
                ok = np.isfinite(frames[rows, bone]).all(axis=(1, 2))
                frames[rows[ok], bone] = turn[ok] @ frames[rows[ok], bone]
        pos[rows, m] = new_m
        for d in descendants(model, e):
            pos[rows, d] += new_e - old_e
    return pos, frames
