"""A small independent BVH reader for the export tests (no Kinetre code): joint name -> (F, 3) world
positions. Position channels replace the joint's OFFSET (Blender's and bvhio's reading); rotation
channels compose in the order written (intrinsic)."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def read_bvh_positions(path) -> tuple[dict[str, np.ndarray], float]:
    tokens = open(path).read().split()
    i = 0
    joints = []                # (name, parent index, offset, channels)
    stack = []
    while tokens[i] != "MOTION":
        t = tokens[i]
        if t in ("ROOT", "JOINT"):
            joints.append([tokens[i + 1], stack[-1] if stack else -1, None, []])
            stack.append(len(joints) - 1)
            i += 2
        elif t == "End":
            # skip "End Site { OFFSET x y z }"
            i += 8
        elif t == "OFFSET":
            joints[stack[-1]][2] = np.array(tokens[i + 1:i + 4], float)
            i += 4
        elif t == "CHANNELS":
            n = int(tokens[i + 1])
            joints[stack[-1]][3] = tokens[i + 2:i + 2 + n]
            i += 2 + n
        elif t == "}":
            stack.pop()
            i += 1
        else:
            i += 1
    frames = int(tokens[i + 2])
    frame_time = float(tokens[i + 5])
    values = np.array(tokens[i + 6:], float).reshape(frames, -1)
    out = {}
    world_r = np.zeros((frames, len(joints), 3, 3))
    world_t = np.zeros((frames, len(joints), 3))
    col = 0
    for j, (name, parent, offset, channels) in enumerate(joints):
        pos = np.tile(offset, (frames, 1))
        rot = np.tile(np.eye(3), (frames, 1, 1))
        for ch in channels:
            v = values[:, col]
            col += 1
            axis = "XYZ".index(ch[0])
            if ch.endswith("position"):
                pos[:, axis] = v
            else:
                rot = rot @ Rotation.from_euler("XYZ"[axis], v[:, None], degrees=True).as_matrix()
        if parent < 0:
            world_r[:, j], world_t[:, j] = rot, pos
        else:
            world_r[:, j] = world_r[:, parent] @ rot
            world_t[:, j] = world_t[:, parent] + np.einsum("fij,fj->fi", world_r[:, parent], pos)
        out[name] = world_t[:, j]
    return out, frame_time
