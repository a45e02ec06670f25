"""A skeleton take (joint positions per frame) as a BVH file in the skeleton's own hierarchy (Kinect-20 for
tracked takes).

BVH stores a rest skeleton (per-joint OFFSET from the parent) and per frame a local rotation per joint.
Tracked joint positions are not a rigid skeleton: bone lengths change from frame to frame, and the angle
between the children of one joint (HipCenter → Spine/HipLeft/HipRight) changes too, which no rotation can
follow. So every joint gets position channels as well (BVH allows them on any joint; like Blender and
bvhio we read a joint's position channels as its full local translation, *replacing* its OFFSET), and the
file reproduces each tracked position to the precision of the printed numbers (1 µm, 1e-6 degree).

The rotations are still meaningful for a viewer that ignores non-root position channels: each joint's world
rotation turns its rest child bones onto the current ones (Kabsch over its tracked children; the minimal
swing from the parent's rotation for a single child; the parent's rotation for a leaf). Read that way the
residual is the bone-length and inter-child-angle change of the take (`rotation_residuals` measures it);
`joint_positions=False` writes that classic root-only layout.

Rest skeleton: OFFSETs are the bone vectors of the first frame where all joints are tracked (per bone,
the first frame where both ends are; 5 cm up where never). The root's OFFSET is zero and its position
channels are absolute, so readers that add OFFSET to root positions and readers that replace it agree.
Untracked joints are filled by carrying their rest bone with the parent's rotation (a lost root holds its
last tracked position), so every number in the file is finite.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import ExportError
from ..rotation import minimal_rotations
from ..skeleton.models import Skeleton

_ORDER = "ZXY"                 # rotation channel order written: Zrotation Xrotation Yrotation (intrinsic)
_UNTRACKED_OFFSET = np.array([0.0, 0.05, 0.0])


def write_bvh(path, frames: list[Skeleton], fps: float, *, joint_positions: bool = True) -> None:
    """Write a skeleton take as BVH (metres, +Y up, the frames' own hierarchy, e.g. Kinect-20).

    Parameters
    ----------
    path : str or Path
        Output .bvh file.
    frames : list of Skeleton
        The take; all frames share one SkeletonModel with a single root; at least one frame must track
        at least one joint.
    fps : float
        Frames per second (Frame Time = 1 / fps).
    joint_positions : bool
        True (default): position channels on every joint, exact positions on re-reading. False: position
        channels on the root only (rotations carry the pose; bones keep their rest lengths).

    Raises
    ------
    ExportError
        Empty take, mixed skeleton models, several roots, nothing tracked, bad fps, unwritable path.
    """
    path = Path(path)
    model = _check(path, frames, fps)
    world_pos, world_rot, offsets = solve_rotations(frames)
    parents = np.array(model.parents)
    root = int(np.flatnonzero(parents < 0)[0])

    f, j = world_pos.shape[:2]
    channels = np.zeros((f, j, 6))           # per joint: position xyz, then Euler angles in _ORDER (degrees)
    for c in range(j):
        p = parents[c]
        if p < 0:
            local_rot, local_pos = world_rot[:, c], world_pos[:, c]
        else:
            parent_t = world_rot[:, p].transpose(0, 2, 1)
            local_rot = parent_t @ world_rot[:, c]
            local_pos = np.einsum("fij,fj->fi", parent_t, world_pos[:, c] - world_pos[:, p])
        channels[:, c, :3] = local_pos
        channels[:, c, 3:] = _euler_degrees(local_rot)

    children = [[c for c in range(j) if parents[c] == i] for i in range(j)]
    lines = ["HIERARCHY"]

    def emit(i: int, depth: int):
        pad = "\t" * depth
        lines.append(f"{pad}{'ROOT' if i == root else 'JOINT'} {model.joints[i]}")
        lines.append(f"{pad}{{")
        offset = np.zeros(3) if i == root else offsets[i]
        lines.append(f"{pad}\tOFFSET {_num(offset)}")
        rot_names = " ".join(f"{a}rotation" for a in _ORDER)
        if i == root or joint_positions:
            lines.append(f"{pad}\tCHANNELS 6 Xposition Yposition Zposition {rot_names}")
        else:
            lines.append(f"{pad}\tCHANNELS 3 {rot_names}")
        for c in children[i]:
            emit(c, depth + 1)
        if not children[i]:
            # a short tip along the incoming bone, so viewers draw the last bone with a direction
            tip = 0.25 * offsets[i] if i != root else np.array([0.0, 0.1, 0.0])
            lines.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {_num(tip)}", f"{pad}\t}}"])
        lines.append(f"{pad}}}")

    emit(root, 0)
    order = _depth_first(root, children)
    lines += ["MOTION", f"Frames: {f}", f"Frame Time: {1.0 / fps:.10f}"]
    for k in range(f):
        row = []
        for i in order:
            if i == root or joint_positions:
                row.append(_num(channels[k, i, :3]))
            row.append(_num(channels[k, i, 3:]))
        lines.append(" ".join(row))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(lines) + "\n")
    except OSError as err:
        raise ExportError(f"{path}: cannot write the BVH file ({err.strerror or err})") from None


def solve_rotations(frames: list[Skeleton]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fill untracked joints and fit a world rotation per joint and frame.

    Returns
    -------
    positions : (F, J, 3) float64
        Tracked positions unchanged; untracked ones filled from the parent (see the module docstring).
    rotations : (F, J, 3, 3) float64
        World rotation of each joint, identity in the rest skeleton.
    offsets : (J, 3) float64
        Rest bone vector (child minus parent) per joint; zero for the root.
    """
    model = frames[0].model
    parents = np.array(model.parents)
    pos = np.stack([s.positions for s in frames])
    tracked = np.stack([s.tracked for s in frames])
    f, j = tracked.shape
    offsets = _rest_offsets(pos, tracked, parents)
    children = [[c for c in range(j) if parents[c] == i] for i in range(j)]
    root = int(np.flatnonzero(parents < 0)[0])

    out_pos = np.zeros((f, j, 3))
    out_rot = np.tile(np.eye(3), (f, j, 1, 1))
    for i in _depth_first(root, children):      # parents before children, every frame at once
        p = parents[i]
        if p < 0:
            # a lost root holds its last tracked position (the first tracked one before that)
            seen = np.where(tracked[:, i], np.arange(f), -1)
            last = np.maximum.accumulate(seen)
            last[last < 0] = np.argmax(tracked[:, i]) if tracked[:, i].any() else 0
            out_pos[:, i] = pos[last, i] if tracked[:, i].any() else 0.0
            parent_rot = np.tile(np.eye(3), (f, 1, 1))
        else:
            parent_rot = out_rot[:, p]
            carried = out_pos[:, p] + parent_rot @ offsets[i]
            out_pos[:, i] = np.where(tracked[:, i, None], pos[:, i], carried)
        kids = children[i]
        if kids:
            now = np.where(tracked[:, kids, None], pos[:, kids] - out_pos[:, i, None], 0.0)   # (F, C, 3)
            out_rot[:, i] = _fit_rotations(parent_rot, offsets[kids], now)
        else:
            out_rot[:, i] = parent_rot
    return out_pos, out_rot, offsets


def rotation_residuals(frames: list[Skeleton]) -> np.ndarray:
    """(F, J) distance between each tracked joint and where the rotations alone (rest OFFSETs, root
    position) put it: the error of a reader that ignores non-root position channels; NaN where untracked."""
    model = frames[0].model
    parents = np.array(model.parents)
    pos, rot, offsets = solve_rotations(frames)
    children = [[c for c in range(len(parents)) if parents[c] == i] for i in range(len(parents))]
    root = int(np.flatnonzero(parents < 0)[0])
    rigid = np.zeros_like(pos)
    for i in _depth_first(root, children):
        p = parents[i]
        rigid[:, i] = pos[:, i] if p < 0 else rigid[:, p] + np.einsum("fij,j->fi", rot[:, p], offsets[i])
    tracked = np.stack([s.tracked for s in frames])
    return np.where(tracked, np.linalg.norm(rigid - np.stack([s.positions for s in frames]), axis=2), np.nan)


def _check(path, frames, fps):
    if not frames:
        raise ExportError(f"{path}: the take has no frames to export")
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise ExportError(f"{path}: fps must be a positive number, got {fps}")
    model = frames[0].model
    for k, s in enumerate(frames):
        if s.model != model:
            raise ExportError(f"{path}: frame {k} has skeleton {s.model.name!r}, frame 0 has {model.name!r}")
    roots = [model.joints[i] for i, p in enumerate(model.parents) if p < 0]
    if len(roots) != 1:
        raise ExportError(f"{path}: BVH needs one root joint, skeleton {model.name!r} has {roots}")
    if not any(s.tracked.any() for s in frames):
        raise ExportError(f"{path}: no frame of the take tracks any joint")
    return model


def _rest_offsets(pos, tracked, parents):
    """Bone vectors from the first fully tracked frame (per bone: first frame with both ends tracked)."""
    j = len(parents)
    offsets = np.zeros((j, 3))
    full = np.flatnonzero(tracked.all(axis=1))
    for c in range(j):
        p = parents[c]
        if p < 0:
            continue
        both = np.flatnonzero(tracked[:, c] & tracked[:, p])
        if full.size:
            k = full[0]
        elif both.size:
            k = both[0]
        else:
            offsets[c] = _UNTRACKED_OFFSET
            continue
        offsets[c] = pos[k, c] - pos[k, p]
    return offsets


def _fit_rotations(parent_rot, rest, now):
    """World rotations (F, 3, 3) taking the rest child bones onto the current ones, every frame at once.

    parent_rot : (F, 3, 3); rest : (C, 3) rest bone vectors; now : (F, C, 3) current bone vectors, zero
    where the child is not tracked. Two or more independent directions: Kabsch (SVD of sum a b^T, with
    the reflection removed). One direction: the minimal swing from where the parent's rotation carries
    it. None: the parent's rotation.
    """
    la = np.linalg.norm(rest, axis=1)
    lb = np.linalg.norm(now, axis=2)
    use = (la[None] > 1e-9) & (lb > 1e-9)      # a zero-length bone (coincident joints) has no direction
    a = np.where(use[..., None], rest[None] / np.maximum(la, 1e-12)[None, :, None], 0.0)      # (F, C, 3)
    b = np.where(use[..., None], now / np.maximum(lb, 1e-12)[..., None], 0.0)
    h = np.einsum("fci,fcj->fij", a, b)
    u, sv, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.transpose(0, 2, 1) @ u.transpose(0, 2, 1)))
    d[d == 0] = 1.0
    fix = np.tile(np.eye(3), (len(h), 1, 1))
    fix[:, 2, 2] = d
    kabsch = vt.transpose(0, 2, 1) @ fix @ u.transpose(0, 2, 1)
    planar = sv[:, 1] > 1e-3 * np.maximum(sv[:, 0], 1e-12)
    # one direction (or collinear ones): swing the parent-carried rest direction onto the current one
    a1, b1 = a.sum(axis=1), b.sum(axis=1)
    swing = minimal_rotations(np.einsum("fij,fj->fi", parent_rot, a1), b1) @ parent_rot
    out = np.where(planar[:, None, None], kabsch, swing)
    return np.where(use.any(axis=1)[:, None, None], out, parent_rot)


def _euler_degrees(rotations):
    """(F, 3, 3) -> (F, 3) intrinsic Euler angles in _ORDER, degrees (the BVH channel values)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)   # gimbal lock: the angles still rebuild the matrix
        return Rotation.from_matrix(rotations).as_euler(_ORDER, degrees=True)


def _depth_first(root, children):
    order, stack = [], [root]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(children[i]))
    return order


def _num(values) -> str:
    return " ".join(f"{v:.6f}" for v in values)
