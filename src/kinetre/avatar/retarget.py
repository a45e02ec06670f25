"""Tracked joints → the avatar's own joint rotations: the avateering paper's Algorithm 1 (§3).

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

from ..affine import affine_inverse
from ..jit import njit
from ..rotation import minimal_rotation_into, minimal_rotations
from ..skeleton.models import KINECT20
from .bonemap import BoneMap, mapping_skeleton
from .load import Avatar

_K = {name: i for i, name in enumerate(KINECT20.joints)}
_LIMBS = (("Shoulder", "Elbow", "Wrist"), ("Hip", "Knee", "Ankle"))
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
        while child is not None and child not in m:   # a joint the avatar lacks (no elbow): aim past it
            child = _FIRST_CHILD.get(child)
        if j == root or child not in m or not _descends(parents, m[child], j):
            continue
        d = p[m[child]] - p[j]
        if np.linalg.norm(d) < 1e-9 * max(float(np.ptp(p)), 1e-12):
            continue                                  # coincident joints: no direction to follow
        aim_from[j], aim_to[j], rest_aim[j] = _K[kj], _K[child], d / np.linalg.norm(d)
        shoulders = "ShoulderLeft" in m and "ShoulderRight" in m
        twist[j] = shoulders and (kj == "Spine" or (kj == "ShoulderCenter" and _descends(parents, m["ShoulderLeft"], j)))
    # a limb that stops at its shoulder or elbow (hip or knee), a game rig's one-bone arm: its last joint
    # follows the limb's tracked end, its rest direction from the joint to the end its part gives
    names, _, rest, _ = mapping_skeleton(avatar)
    ends = bonemap.weights() @ rest if len(names) == len(bonemap.names) else None
    if ends is not None:
        for kj, j in m.items():
            part, side = (kj[:-4], "Left") if kj.endswith("Left") else (kj[:-5], "Right")
            chain = next((parts for parts in _LIMBS if part in parts[:2]), None)
            if aim_from[j] >= 0 or not kj.endswith(("Left", "Right")) or chain is None or \
                    chain[2] + side not in bonemap.derived:
                continue
            d = ends[_K[chain[2] + side]] - p[j]
            if np.linalg.norm(d) > 1e-9 * max(float(np.ptp(p)), 1e-12):
                aim_from[j], aim_to[j], rest_aim[j] = _K[kj], _K[chain[2] + side], d / np.linalg.norm(d)
    # the torso frame from what maps: a chibi without elbows still has shoulders, one without a neck a head
    side = np.zeros(3)
    for a, b in (("ShoulderLeft", "ShoulderRight"), ("HipLeft", "HipRight")):
        if a in m and b in m:
            side = side + p[m[b]] - p[m[a]]
    sh = p[m["ShoulderRight"]] - p[m["ShoulderLeft"]] if "ShoulderLeft" in m and "ShoulderRight" in m else side
    top = m["ShoulderCenter"] if "ShoulderCenter" in m else m["Head"]
    frame = _torso(p[top] - p[root], side)
    f = bonemap.facing
    yaw = np.arctan2(f[0], f[2])
    c, s = np.cos(yaw), np.sin(yaw)
    align = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    legs = [np.linalg.norm(p[m[f"Hip{x}"]] - p[m[f"Knee{x}"]]) + np.linalg.norm(p[m[f"Knee{x}"]] - p[m[f"Ankle{x}"]])
            for x in ("Left", "Right") if all(f"{k}{x}" in m for k in ("Hip", "Knee", "Ankle"))]
    if not legs and ends is not None:               # a one-bone leg: to the end its part gives
        legs = [np.linalg.norm(ends[_K[f"Hip{x}"]] - ends[_K[f"Knee{x}"]]) +
                np.linalg.norm(ends[_K[f"Knee{x}"]] - ends[_K[f"Ankle{x}"]]) for x in ("Left", "Right")
                if all(f"{k}{x}" in m or f"{k}{x}" in bonemap.derived for k in ("Hip", "Knee", "Ankle"))]
    if not legs:                                      # no whole leg: the hip centre's height stands for it
        legs = [max(float(p[root, 1] - p[:, 1].min()), 1e-9)]
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
             state: RetargetState | None = None, root_turns: np.ndarray | None = None) -> AvatarMotion:
    """Algorithm 1 steps 2–6 for T frames of a Kinect-20 skeleton.

    Parameters
    ----------
    positions : (T, 20, 3) float64
        Tracked joints (metres, +Y up, facing +Z); rows of untracked joints may be NaN.
    tracked : (T, 20) bool
    state : RetargetState, optional
        Carried across calls (live streams); updated in place. A fresh state starts from the bind pose.
    root_turns : (T, 3, 3) float64, optional
        The source's own hips rotation from its T-pose (Kinetre's frame; `Take.hips_turns` of a VRM
        Animation): where finite it is the root's rotation, in place of the torso frame's fit, so a take
        Kinetre wrote on the normalised humanoid (avatar/normalized.py) turns the hips as it was written.

    Returns
    -------
    AvatarMotion

    Notes
    -----
    One compiled pass per frame over the joints (`_frames`, numba), the same loop as the page's
    TypeScript (web/src/avatar/retarget.ts).
    """
    state = RetargetState() if state is None else state
    pos = np.asarray(positions, dtype=np.float64)
    ok = np.asarray(tracked, dtype=bool) & np.isfinite(pos).all(axis=2)
    src = np.where(ok[..., None], pos, 0.0) @ plan.align.T         # Kinetre frame -> the avatar's facing
    n = len(plan.order)
    last = np.tile(np.eye(3), (n, 1, 1)) if state.relative is None else state.relative.copy()
    displacement = np.ascontiguousarray(_root_displacement(plan, src, ok, pos, state))
    turns = np.zeros((len(pos), 3, 3))
    turned = np.zeros(len(pos), dtype=np.bool_)
    if root_turns is not None:
        r = np.asarray(root_turns, dtype=np.float64)
        turned = np.isfinite(r).all(axis=(1, 2))
        # R(hips) = a R_T aᵀ: the normalised humanoid's hips turn (C(hips) = I) in the avatar's facing
        turns[turned] = plan.align @ r[turned] @ plan.align.T
    rot, world, local = _frames(src, ok, displacement, last, turns, turned, plan.order, plan.parents, plan.root, _mover(plan),
                                plan.aim_from, plan.aim_to, plan.twist, plan.rest_aim, plan.rest_shoulders,
                                plan.root_frame, plan.bind_linear, plan.bind_positions, plan.real_parents,
                                plan.fixed_parent, _K["HipCenter"], _K["ShoulderCenter"], _K["HipLeft"],
                                _K["HipRight"], _K["ShoulderLeft"], _K["ShoulderRight"])
    state.relative = last
    return AvatarMotion(world, local, rot)


def _mover(plan) -> int:
    j = plan.root
    while plan.parents[j] >= 0:
        j = plan.parents[j]
    return int(j)


@njit(cache=True)
def _min_rotation(u, v):
    """Smallest rotation turning direction u onto v (any length)."""
    out = np.empty((3, 3))
    minimal_rotation_into(u / max(np.sqrt(u @ u), 1e-12), v / max(np.sqrt(v @ v), 1e-12), out)
    return out


@njit(cache=True)
def _mm(a, b):
    """Small dense product a @ b by loops (BLAS calls cost more than the work at 3x3 and 4x4)."""
    out = np.zeros((a.shape[0], b.shape[1]))
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            aik = a[i, k]
            for j in range(b.shape[1]):
                out[i, j] += aik * b[k, j]
    return out


@njit(cache=True)
def _mv(a, v):
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            out[i] += a[i, k] * v[k]
    return out


@njit(cache=True)
def _affine_inverse(m):
    """Inverse of a 4x4 affine matrix [A | t; 0 1] = [A⁻¹ | −A⁻¹ t; 0 1] (A⁻¹ by the adjugate)."""
    a = m[:3, :3]
    inv = np.zeros((3, 3))
    inv[0, 0] = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    inv[0, 1] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    inv[0, 2] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    inv[1, 0] = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    inv[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    inv[1, 2] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    inv[2, 0] = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    inv[2, 1] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    inv[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    inv /= a[0, 0] * inv[0, 0] + a[0, 1] * inv[1, 0] + a[0, 2] * inv[2, 0]
    out = np.eye(4)
    out[:3, :3] = inv
    out[:3, 3] = -_mv(inv, m[:3, 3])
    return out


@njit(cache=True)
def _skew(a):
    k = np.zeros((3, 3))
    k[0, 1], k[0, 2], k[1, 2] = -a[2], a[1], -a[0]
    k[1, 0], k[2, 0], k[2, 1] = a[2], -a[1], a[0]
    return k


@njit(cache=True)
def _torso(up, side):
    """Columns (side ⟂ up, up, side × up); all zeros when degenerate."""
    out = np.zeros((3, 3))
    nu = np.sqrt(up @ up)
    if nu < 1e-12:
        return out
    y = up / nu
    x = side - (side @ y) * y
    nx = np.sqrt(x @ x)
    if nx < 1e-12:
        return out
    x = x / nx
    out[:, 0], out[:, 1], out[:, 2] = x, y, np.cross(x, y)
    return out


@njit(cache=True)
def _frames(src, ok, displacement, last, turns, turned, order, parents, root, mover, aim_from, aim_to, twist, rest_aim,
            rest_shoulders, root_frame, bind_linear, bind_positions, real_parents, fixed_parent,
            hc, sc, hl, hr, sl, sr):
    t_count, n = src.shape[0], len(order)
    rot = np.zeros((t_count, n, 3, 3))
    world = np.zeros((t_count, n, 4, 4))
    local = np.zeros((t_count, n, 4, 4))
    eye = np.eye(3)
    for t in range(t_count):
        sh_ok = ok[t, sl] and ok[t, sr]
        shoulders = src[t, sr] - src[t, sl]
        for j in order:
            vp = parents[j]
            parent = eye if vp < 0 else rot[t, vp].copy()
            valid = False
            w = eye
            if j == root and turned[t]:
                w = turns[t].copy()
                valid = True
            elif j == root:
                side = np.zeros(3)
                pairs = 0
                if ok[t, hl] and ok[t, hr]:
                    side += src[t, hr] - src[t, hl]
                    pairs += 1
                if sh_ok:
                    side += shoulders
                    pairs += 1
                if ok[t, hc] and ok[t, sc] and pairs > 0:
                    frame = _torso(src[t, sc] - src[t, hc], side)
                    if frame[0, 1] != 0.0 or frame[1, 1] != 0.0 or frame[2, 1] != 0.0:
                        w = _mm(frame, root_frame.T)
                        valid = True
            elif aim_from[j] >= 0:
                s = src[t, aim_to[j]] - src[t, aim_from[j]]
                if ok[t, aim_from[j]] and ok[t, aim_to[j]] and np.sqrt(s @ s) > 1e-9:
                    w = _mm(_min_rotation(_mv(parent, rest_aim[j]), s), parent)
                    valid = True
                    if twist[j] and sh_ok:
                        w = _twisted(w, rest_shoulders, s, shoulders)
            if valid:
                last[j] = _mm(parent.T, w)
            rot[t, j] = _mm(parent, last[j])
            world[t, j, :3, :3] = _mm(rot[t, j], bind_linear[j])
            if vp < 0:
                world[t, j, :3, 3] = bind_positions[j]
                if j == mover:              # the whole armature travels, so no bone above the hips stretches
                    world[t, j, :3, 3] += displacement[t]
            else:
                world[t, j, :3, 3] = world[t, vp, :3, 3] + _mv(parent, bind_positions[j] - bind_positions[vp])
            world[t, j, 3, 3] = 1.0
        for j in range(n):
            above = fixed_parent[j] if real_parents[j] < 0 else _mm(world[t, real_parents[j]], fixed_parent[j])
            local[t, j] = _mm(_affine_inverse(above), world[t, j])
    return rot, world, local


@njit(cache=True)
def _twisted(w, rest_side, bone, side):
    """Turn `w` about the bone so the carried rest shoulder line best meets the tracked one."""
    axis = bone / max(np.sqrt(bone @ bone), 1e-12)
    a = _mv(w, rest_side)
    a = a - (a @ axis) * axis
    b = side - (side @ axis) * axis
    if np.sqrt(a @ a) <= 1e-9 or np.sqrt(b @ b) <= 1e-9:
        return w
    angle = np.arctan2(np.cross(a, b) @ axis, a @ b)
    k = _skew(axis)
    return _mm(np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * _mm(k, k), w)


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


# ---- fingers ------------------------------------------------------------------------------------------

def retarget_fingers(avatar: Avatar, plan: RetargetPlan, fingers, motion: AvatarMotion,
                     hands: np.ndarray) -> AvatarMotion:
    """The body's motion with the finger bones following tracked hands, Algorithm 1 per finger segment.

    Each finger bone (joint c_i → c_{i+1} of a chain in `fingers`, a `kinetre.avatar.fingers.FingerMap`;
    the last joint's bone points at its child node, and a tip joint without one is left alone) follows one
    segment of MediaPipe's finger (landmarks MCP → PIP → DIP → tip, the thumb's CMC → MCP → IP → tip), the
    first bone the first segment and the last the last: with s the segment's direction and q_parent the
    parent's world rotation, q_world = minrot(q_parent d_i → s) · q_parent, as for the body. A bone whose
    hand is not seen in a frame keeps its last local rotation (at first the bind pose). Joints below the
    fingers are carried along.

    hands : (T, 2, 21, 3) left and right hand landmarks in Kinetre's frame (NaN where not seen).
    """
    from ..skeleton.mediapipe import FINGERS
    hands = np.asarray(hands, dtype=np.float64)
    t_count = len(motion)
    if hands.shape != (t_count, 2, 21, 3):
        raise ValueError(f"hands must be ({t_count}, 2, 21, 3), got {hands.shape}")
    p = plan.bind_positions
    aims = {}                                        # joint -> (rest direction, landmark from, landmark to)
    for (side, finger), chain in fingers.chains.items():
        bones = []
        for i, j in enumerate(chain):
            end = p[chain[i + 1]] if i + 1 < len(chain) else _child_node_position(avatar, j)
            if end is not None and np.linalg.norm(end - p[j]) > 1e-12:
                bones.append((j, (end - p[j]) / np.linalg.norm(end - p[j])))
        marks = FINGERS[finger]
        for b, (j, d) in enumerate(bones):
            k = int(round(b * (len(marks) - 2) / max(len(bones) - 1, 1)))
            aims[j] = (d, side, marks[k], marks[k + 1])
    if not aims:
        return motion
    src = hands @ plan.align.T
    rot, world, local = motion.rotations.copy(), motion.world.copy(), motion.local.copy()
    moved = np.zeros(len(plan.order), dtype=bool)
    eye = np.eye(3)
    for j in plan.order:
        vp = plan.parents[j]
        if j not in aims and not (vp >= 0 and moved[vp]):
            continue
        moved[j] = True
        parent = np.broadcast_to(eye, (t_count, 3, 3)) if vp < 0 else rot[:, vp]
        if j in aims:
            d, side, a, b = aims[j]
            s = src[:, side, b] - src[:, side, a]
            ok = np.isfinite(s).all(axis=1) & (np.linalg.norm(np.nan_to_num(s), axis=1) > 1e-9)
            w = minimal_rotations(_unit(np.einsum("tij,j->ti", parent, d)), _unit(np.nan_to_num(s))) @ parent
            relative = _hold(np.swapaxes(parent, 1, 2) @ w, ok, eye)
        else:         # carried along: what it had relative to its parent
            relative = np.swapaxes(motion.rotations[:, vp], 1, 2) @ motion.rotations[:, j]
        rot[:, j] = parent @ relative
        world[:, j, :3, :3] = rot[:, j] @ plan.bind_linear[j]
        if vp >= 0:
            world[:, j, :3, 3] = world[:, vp, :3, 3] + np.einsum("tij,j->ti", rot[:, vp], p[j] - p[vp])
    for j in range(len(plan.order)):
        rp = plan.real_parents[j]
        if moved[j] or (rp >= 0 and moved[rp]):   # a joint whose glTF parent moved gets a new local matrix too
            above = np.broadcast_to(plan.fixed_parent[j], (t_count, 4, 4)) if rp < 0 else \
                world[:, rp] @ plan.fixed_parent[j]
            local[:, j] = affine_inverse(above) @ world[:, j]
    return AvatarMotion(world, local, rot)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _child_node_position(avatar: Avatar, joint: int) -> np.ndarray | None:
    """Bind-pose world position of the first child node of a joint's node (an end bone), if any."""
    node = avatar.joints[joint]
    children = np.flatnonzero(avatar.node_parents == node)
    if not len(children):
        return None
    # rest_world is the bind pose for joints; a child node follows its joint rigidly
    offset = np.linalg.solve(avatar.rest_world[node], avatar.rest_world[children[0]])
    return (avatar.bind_world[joint] @ offset)[:3, 3]
