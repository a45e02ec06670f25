"""Tracked joints → the avatar's own joint rotations: the avateering paper's Algorithm 1 (SPEC §6.1).

Off-line (`plan_retarget`): for each avatar joint J_i that owns a tracked bone (i → c), the bone's rest
direction d_i = (J_c − J_i)/‖·‖ from the bind pose (bone lengths L_i are the avatar's and never change).

Per frame (`retarget`), parents before children:
  s_i = (P_c − P_i)/‖·‖,   q_lo = the minimal rotation (axis m_i = d_i × s_i, angle θ_i = acos(d_i·s_i))
  taking the parent-carried rest direction q_parent·d_i onto s_i, so the world rotation of J_i is
  q_i^world = q_lo · q_parent^world, and the local rotation written for the avatar is
  q_i = (q_parent^world)⁻¹ · q_i^world (the paper's q_i = (q_pa)⁻¹ · q_lo, step 6); each joint moves to
  parent position + L_i s_i (step 5) because its local translation stays the bind one.
Twist: the minimal rotation leaves the turn about the bone free; it is taken from the parent (composed with
the parent's world rotation, so a whole-body turn turns every limb), and for the spine and chest from the
shoulder line (the turn about s_i that best aligns the avatar's shoulders with the tracked ones) *(ours)*.
Root: the rotation taking the avatar's torso frame (up = hips → shoulder centre, side = left → right hip
plus shoulder) to the tracked one; root translation = the tracked hip centre's displacement from the first
tracked frame, times (avatar leg length / tracked leg length), given to the top joint above the hips (the
armature, so IK helper bones travel along). A joint or bone that is not tracked in a
frame keeps its last local rotation (the root its last place): no NaN, ever.

Frames: the tracked skeleton is in Kinetre's frame (+Y up, facing +Z, metres); the avatar's world is +Y up
facing `BoneMap.facing`. A fixed turn about +Y (`RetargetPlan.align`) takes the one to the other, so a
person facing the camera drives the avatar facing its own front.

Everything is vectorised over frames (one pass over the joints), so a whole take costs microseconds per
frame; `RetargetState` carries the last rotations from one call to the next for live streams.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..export.bvh import _min_rotations as min_rotations
from ..skeleton.models import KINECT20
from .bonemap import BoneMap
from .load import Avatar

_K = {name: i for i, name in enumerate(KINECT20.joints)}
_FIRST_CHILD = {KINECT20.joints[p]: KINECT20.joints[c] for c, p in reversed(list(enumerate(KINECT20.parents)))
                if p >= 0}


@dataclass(frozen=True, eq=False)
class RetargetPlan:
    """Algorithm 1's off-line step as plain arrays (also sent to the studio page as JSON).

    Attributes
    ----------
    order : (J,) int64
        Joints, parents before children (in `parents`).
    parents : (J,) int64
        Kinematic parent joint (-1: none): the skin's hierarchy, except that a mapped joint not under the
        root (an IK foot bone hung on the armature) hangs on the joint of its Kinect parent.
    real_parents : (J,) int64
        The glTF hierarchy's nearest joint ancestor (-1: none), for local transforms.
    fixed_parent : (J, 4, 4) float64
        The glTF parent node's rest world matrix relative to `real_parents`' joint (its world matrix where
        there is no joint above; identity where the parent is that joint).
    root : int
        The joint playing HipCenter.
    aim_from, aim_to : (J,) int64
        Kinect joints (indices in KINECT20) of the bone each joint follows, -1 for none.
    twist : (J,) bool
        Joints whose turn about their bone follows the shoulder line (spine, chest).
    rest_aim : (J, 3) float64
        d_i: unit rest direction of the followed bone (avatar world, bind pose).
    rest_shoulders : (3,) float64
        Unit left → right shoulder direction in the bind pose.
    root_frame : (3, 3) float64
        Columns: side, up, forward of the avatar's torso in the bind pose.
    bind_linear : (J, 3, 3) float64
        Linear part of each joint's bind world matrix.
    bind_positions : (J, 3) float64
    align : (3, 3) float64
        Rotation about +Y taking Kinetre's facing (+Z) to the avatar's.
    leg_length : float
        Avatar hip → knee → ankle length (mean of both legs), world units.
    """

    order: np.ndarray
    parents: np.ndarray
    real_parents: np.ndarray
    fixed_parent: np.ndarray
    root: int
    aim_from: np.ndarray
    aim_to: np.ndarray
    twist: np.ndarray
    rest_aim: np.ndarray
    rest_shoulders: np.ndarray
    root_frame: np.ndarray
    bind_linear: np.ndarray
    bind_positions: np.ndarray
    align: np.ndarray
    leg_length: float

    def to_json(self) -> dict:
        """The plan as JSON-able lists (for the page's TypeScript retargeter)."""
        out = {}
        for k, v in self.__dict__.items():
            out[k] = v.tolist() if isinstance(v, np.ndarray) else v
        return out


@dataclass
class RetargetState:
    """What carries over between calls for a live stream: last local rotations, root place, references."""

    relative: np.ndarray | None = None          # (J, 3, 3) last parent-relative world rotation per joint
    hip_reference: np.ndarray | None = None     # (3,) first tracked hip centre (source frame, aligned)
    displacement: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float | None = None                  # avatar leg / source leg


@dataclass(frozen=True, eq=False)
class AvatarMotion:
    """Retargeted frames: each joint's world matrix (what skinning needs) and local matrix (what a glTF
    or BVH file stores).

    Attributes
    ----------
    world : (T, J, 4, 4) float64
    local : (T, J, 4, 4) float64
        Relative to the glTF parent node (joint or not).
    rotations : (T, J, 3, 3) float64
        World rotation of each joint relative to its bind pose (the paper's q^world).
    """

    world: np.ndarray
    local: np.ndarray
    rotations: np.ndarray

    def __len__(self) -> int:
        return int(self.world.shape[0])

    @property
    def positions(self) -> np.ndarray:
        """(T, J, 3) joint positions."""
        return self.world[:, :, :3, 3]


def plan_retarget(avatar: Avatar, bonemap: BoneMap) -> RetargetPlan:
    """Algorithm 1 step 1 (off-line): rest directions, lengths, the root frame and the facing turn."""
    m = bonemap.joints
    p = avatar.bind_positions
    n = len(p)
    real = avatar.joint_parents.copy()
    root = m["HipCenter"]
    under_root = np.array([_descends(real, j, root) for j in range(n)])
    parents = real.copy()
    for kj, j in m.items():
        if not under_root[j] and j != root:            # hang it on the joint of its Kinect parent
            k = KINECT20.parents[_K[kj]]
            while k >= 0 and KINECT20.joints[k] not in m:
                k = KINECT20.parents[k]
            if k >= 0:
                parents[j] = m[KINECT20.joints[k]]
    order = _order(parents)

    aim_from = np.full(n, -1, dtype=np.int64)
    aim_to = np.full(n, -1, dtype=np.int64)
    twist = np.zeros(n, dtype=bool)
    rest_aim = np.zeros((n, 3))
    for kj, j in m.items():
        child = _FIRST_CHILD.get(kj)
        if j == root or child not in m or not _descends(parents, m[child], j):
            continue
        d = p[m[child]] - p[j]
        if np.linalg.norm(d) < 1e-9 * max(float(np.ptp(p)), 1e-12):
            continue                                  # coincident joints: no direction to follow
        aim_from[j], aim_to[j], rest_aim[j] = _K[kj], _K[child], d / np.linalg.norm(d)
        shoulders = "ShoulderLeft" in m and "ShoulderRight" in m
        twist[j] = shoulders and (kj == "Spine" or (kj == "ShoulderCenter" and _descends(parents, m["ShoulderLeft"], j)))
    sh = p[m["ShoulderRight"]] - p[m["ShoulderLeft"]]
    frame = torso_frame(p[m["ShoulderCenter"]] - p[root],
                        (p[m["HipRight"]] - p[m["HipLeft"]]) + sh)
    f = bonemap.facing
    yaw = np.arctan2(f[0], f[2])
    c, s = np.cos(yaw), np.sin(yaw)
    align = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    legs = [np.linalg.norm(p[m[f"Hip{x}"]] - p[m[f"Knee{x}"]]) + np.linalg.norm(p[m[f"Knee{x}"]] - p[m[f"Ankle{x}"]])
            for x in ("Left", "Right")]
    # a joint's glTF parent world = its nearest joint ancestor's world x the fixed rest offset between them
    fixed = np.tile(np.eye(4), (n, 1, 1))
    for j, node in enumerate(avatar.joints):
        parent_node = avatar.node_parents[node]
        if parent_node < 0:
            continue
        above = avatar.rest_world[parent_node]
        fixed[j] = above if real[j] < 0 else np.linalg.solve(avatar.rest_world[avatar.joints[real[j]]], above)
    bind = avatar.bind_world
    return RetargetPlan(order, parents, real, fixed, int(root), aim_from, aim_to, twist, rest_aim,
                        sh / max(np.linalg.norm(sh), 1e-12), frame, bind[:, :3, :3].copy(), p.copy(), align,
                        float(np.mean(legs)))


def torso_frame(up: np.ndarray, side: np.ndarray) -> np.ndarray:
    """(..., 3, 3) orthonormal frames, columns (side ⟂ up, up, side × up); NaN where degenerate."""
    y = up / np.linalg.norm(up, axis=-1, keepdims=True)
    x = side - np.sum(side * y, axis=-1, keepdims=True) * y
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def source_leg_length(positions: np.ndarray, tracked: np.ndarray) -> float | None:
    """Median hip → knee → ankle length over the frames where a whole leg is tracked (None if never)."""
    lengths = []
    for s in ("Left", "Right"):
        h, k, a = _K[f"Hip{s}"], _K[f"Knee{s}"], _K[f"Ankle{s}"]
        ok = tracked[:, h] & tracked[:, k] & tracked[:, a]
        lengths.append(np.linalg.norm(positions[ok, h] - positions[ok, k], axis=1)
                       + np.linalg.norm(positions[ok, k] - positions[ok, a], axis=1))
    both = np.concatenate(lengths)
    both = both[np.isfinite(both) & (both > 0)]
    return float(np.median(both)) if both.size else None


def retarget(plan: RetargetPlan, positions: np.ndarray, tracked: np.ndarray,
             state: RetargetState | None = None) -> AvatarMotion:
    """Algorithm 1 steps 2–6 for T frames of a Kinect-20 skeleton.

    Parameters
    ----------
    positions : (T, 20, 3) float64
        Tracked joints (metres, +Y up, facing +Z); rows of untracked joints may be NaN.
    tracked : (T, 20) bool
    state : RetargetState, optional
        Carried across calls (live streams); updated in place. A fresh state starts from the bind pose.

    Returns
    -------
    AvatarMotion
    """
    state = RetargetState() if state is None else state
    pos = np.asarray(positions, dtype=np.float64)
    ok = np.asarray(tracked, dtype=bool) & np.isfinite(pos).all(axis=2)
    src = np.where(ok[..., None], pos, 0.0) @ plan.align.T         # Kinetre frame -> the avatar's facing
    t, n = len(src), len(plan.order)
    eye = np.broadcast_to(np.eye(3), (t, 3, 3))
    last = np.tile(np.eye(3), (n, 1, 1)) if state.relative is None else state.relative.copy()
    rot = np.zeros((t, n, 3, 3))
    place = np.zeros((t, n, 3))
    shoulders = src[:, _K["ShoulderRight"]] - src[:, _K["ShoulderLeft"]]
    shoulders_ok = ok[:, _K["ShoulderRight"]] & ok[:, _K["ShoulderLeft"]]
    mover = plan.root
    while plan.parents[mover] >= 0:
        mover = plan.parents[mover]
    for j in plan.order:
        vp = plan.parents[j]
        parent = eye if vp < 0 else rot[:, vp]
        if j == plan.root:
            world, valid = _root_rotation(plan, src, ok)
        elif plan.aim_from[j] >= 0:
            a, b = plan.aim_from[j], plan.aim_to[j]
            s = src[:, b] - src[:, a]
            valid = ok[:, a] & ok[:, b] & (np.linalg.norm(s, axis=1) > 1e-9)
            world = min_rotations(parent @ plan.rest_aim[j], np.where(valid[:, None], s, 1.0)) @ parent
            if plan.twist[j]:
                world = _twist(world, plan.rest_shoulders, s, shoulders, valid & shoulders_ok)
        else:
            world, valid = None, None
        if world is None:                               # an untracked role: rigid with its parent
            relative = np.broadcast_to(last[j], (t, 3, 3))
        else:
            relative = _hold(np.einsum("tba,tbc->tac", parent, world), valid, last[j])
        rot[:, j] = parent @ relative
        last[j] = relative[-1]
        if vp < 0:
            place[:, j] = plan.bind_positions[j]
            if j == mover:                  # the whole armature travels, so no bone above the hips stretches
                place[:, j] += _root_displacement(plan, src, ok, pos, state)
        else:
            place[:, j] = place[:, vp] + parent @ (plan.bind_positions[j] - plan.bind_positions[vp])
    state.relative = last

    world = np.zeros((t, n, 4, 4))
    world[:, :, :3, :3] = rot @ plan.bind_linear
    world[:, :, :3, 3] = place
    world[:, :, 3, 3] = 1.0
    parent_world = np.broadcast_to(plan.fixed_parent, (t, n, 4, 4)).copy()
    has = plan.real_parents >= 0
    parent_world[:, has] = world[:, plan.real_parents[has]] @ plan.fixed_parent[has]
    local = np.linalg.solve(parent_world, world)
    return AvatarMotion(world, local, rot)


def _root_rotation(plan, src, ok):
    hc, sc = _K["HipCenter"], _K["ShoulderCenter"]
    side = np.zeros_like(src[:, 0])
    pairs = 0
    for a, b in (("HipLeft", "HipRight"), ("ShoulderLeft", "ShoulderRight")):
        both = ok[:, _K[a]] & ok[:, _K[b]]
        side += np.where(both[:, None], src[:, _K[b]] - src[:, _K[a]], 0.0)
        pairs = pairs + both
    up = src[:, sc] - src[:, hc]
    with np.errstate(invalid="ignore", divide="ignore"):
        frame = torso_frame(up, side)
    valid = ok[:, hc] & ok[:, sc] & (pairs > 0) & np.isfinite(frame).all(axis=(1, 2))
    frame = np.where(valid[:, None, None], frame, np.eye(3))
    return frame @ plan.root_frame.T, valid


def _twist(world, rest_side, bone, side, valid):
    """Turn `world` about the bone (T, 3) so the carried rest shoulder line best meets the tracked one."""
    axis = bone / np.maximum(np.linalg.norm(bone, axis=1, keepdims=True), 1e-12)
    a = world @ rest_side
    a = a - np.sum(a * axis, axis=1, keepdims=True) * axis
    b = side - np.sum(side * axis, axis=1, keepdims=True) * axis
    angle = np.arctan2(np.sum(np.cross(a, b) * axis, axis=1), np.sum(a * b, axis=1))
    good = valid & (np.linalg.norm(a, axis=1) > 1e-9) & (np.linalg.norm(b, axis=1) > 1e-9)
    angle = np.where(good, angle, 0.0)
    return _axis_angle(axis, angle) @ world


def _axis_angle(axis, angle):
    """(T, 3, 3) rotations by `angle` (T,) about unit `axis` (T, 3) (Rodrigues)."""
    k = np.zeros((len(axis), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = axis[:, 2], -axis[:, 1], axis[:, 0]
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def _hold(relative, valid, start):
    """Frames where `valid` is False take the last valid frame's value (before any: `start`)."""
    t = len(valid)
    seen = np.maximum.accumulate(np.where(valid, np.arange(t), -1))
    return np.where((seen >= 0)[:, None, None], relative[np.maximum(seen, 0)], start)


def _root_displacement(plan, src, ok, raw, state):
    """(T, 3) root translation: hip centre displacement since the first tracked frame, leg-length scaled."""
    hc = _K["HipCenter"]
    valid = ok[:, hc]
    if state.scale is None:
        leg = source_leg_length(raw, ok)
        if leg is not None:
            state.scale = plan.leg_length / leg
    if state.hip_reference is None and valid.any():
        state.hip_reference = src[int(np.argmax(valid)), hc].copy()
    if state.hip_reference is None or state.scale is None:
        return np.broadcast_to(state.displacement, (len(src), 3))
    moved = state.scale * (src[:, hc] - state.hip_reference)
    held = _hold(moved[:, :, None], valid, state.displacement[:, None])[:, :, 0]
    state.displacement = held[-1].copy()
    return held


def _descends(parents, j, ancestor) -> bool:
    while j >= 0:
        if j == ancestor:
            return True
        j = parents[j]
    return False


def _order(parents) -> np.ndarray:
    children = [[] for _ in parents]
    for c, p in enumerate(parents):
        if p >= 0:
            children[p].append(c)
    order, stack = [], [j for j, p in enumerate(parents) if p < 0][::-1]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(children[j][::-1])
    return np.array(order, dtype=np.int64)
