"""An avatar driven by its own animation (`kinetre avatar A.glb --motion A.glb#CLIP`) plays it as its artist
made it: when the motion's own skeleton is the avatar's (the same joint names, and bone lengths that match
the avatar's bind pose), each joint takes the source's world position and its rotation from the bind pose
as the source has it, twist included, with no Kinect-20 retarget in between.
"""
from __future__ import annotations

import numpy as np

from ..affine import affine_inverse
from ..motion.gltf import node_names
from ..motion.take import Take
from .load import Avatar
from .retarget import AvatarMotion

FOUND = 0.9  # share of the avatar's joints the source must name
LENGTH = 0.02  # bone lengths may differ by this share of the avatar's height


def own_motion(avatar: Avatar, take: Take) -> AvatarMotion | None:
    """The avatar's motion from `take` when the take is on the avatar's own skeleton (`take.native` or the
    take itself), else None."""
    source = take.native if take.native is not None else take
    found = own_joints(avatar, source)
    return None if found is None else _play(avatar, source, found)


def own_joints(avatar: Avatar, take: Take) -> np.ndarray | None:
    """(J,) per avatar joint its joint in `take` (-1: none) when `take` (with bone frames) is on the avatar's
    own skeleton, else None."""
    source = take
    if source.bone_frames is None:
        return None
    index = {name: k for k, name in enumerate(source.model.joints)}
    # named as a glTF take names them (an unnamed node is "node<index>" there)
    names = node_names(avatar.doc, [int(n) for n in avatar.joints])
    found = np.array([index.get(name, -1) for name in names])
    if (found >= 0).mean() < FOUND:
        return None
    bind = avatar.bind_positions
    height = float(np.ptp(bind[:, 1])) or float(np.ptp(bind, axis=0).max())
    first = source.positions[0]
    for j, p in enumerate(avatar.joint_parents):
        if p < 0 or found[j] < 0 or found[p] < 0:
            continue
        rest_length = np.linalg.norm(bind[j] - bind[p])
        now_length = np.linalg.norm(first[found[j]] - first[found[p]])
        if abs(rest_length - now_length) > LENGTH * height:
            return None
    return found


def _polar(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    return u @ vt


def _play(avatar: Avatar, source: Take, found: np.ndarray) -> AvatarMotion:
    t = len(source)
    nodes = len(avatar.node_parents)
    joint_of = {int(n): j for j, n in enumerate(avatar.joints)}
    # a joint's own frame is the frame that carries any of its children (`Take.bone_frames`)
    own = {}
    for k, p in enumerate(source.model.parents):
        if p >= 0 and p not in own:
            own[p] = k
    world = np.tile(avatar.rest_world, (t, 1, 1, 1))
    moved = np.zeros(nodes, bool)
    order = _parents_first(avatar.node_parents)
    for n in order:
        j = joint_of.get(int(n))
        parent = avatar.node_parents[n]
        if j is not None and found[j] >= 0:
            rest = avatar.rest_world[n]
            k = found[j]
            if k in own:
                turn = source.bone_frames[:, own[k]] @ _polar(rest[:3, :3]).T
            elif parent >= 0 and moved[parent]:
                turn = _polar(world[:, parent, :3, :3] @ np.linalg.inv(avatar.rest_world[parent, :3, :3]))
            else:
                turn = np.tile(np.eye(3), (t, 1, 1))
            world[:, n, :3, :3] = turn @ rest[:3, :3]
            world[:, n, :3, 3] = source.positions[:, k]
            moved[n] = True
        elif parent >= 0 and moved[parent]:  # carried rigidly by its parent
            world[:, n] = world[:, parent] @ (affine_inverse(avatar.rest_world[parent]) @ avatar.rest_world[n])
            moved[n] = True
    local = world.copy()
    for n in range(nodes):
        parent = avatar.node_parents[n]
        if parent >= 0:
            local[:, n] = affine_inverse(world[:, parent]) @ world[:, n]
    joints = avatar.joints
    rotations = world[:, joints, :3, :3] @ np.linalg.inv(avatar.rest_world[joints, :3, :3])
    return AvatarMotion(world[:, joints], local[:, joints], _polar(rotations))


def _parents_first(parents: np.ndarray) -> list[int]:
    children: dict[int, list[int]] = {}
    for n, p in enumerate(parents):
        children.setdefault(int(p), []).append(n)
    order, stack = [], list(reversed(children.get(-1, [])))
    while stack:
        n = stack.pop()
        order.append(n)
        stack.extend(reversed(children.get(n, [])))
    return order
