"""A take's node matrices for the page's physics replay: one transform block per frame, concatenated.

Each block is the binary node-transform block the studio publishes (kinetre/wire/transforms.py: 32-byte
header, then N × 12 float32, the top three rows of each node matrix): seq = frame index, t_source = the frame's time in ms from the
start. The page (web/src/physics/TakeReplay.ts) carries the sphere proxies with these frames, so the
replayed physics sees exactly the take's deformation.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..deform.pose import GraphPose
from ..errors import BadMotionError
from ..graph.graph import DeformationGraph
from ..wire.transforms import HEADER, TransformBlockError, block_size, pack_transforms, unpack_transforms


def write_take_transforms(path: str | Path, graph: DeformationGraph, poses: list[GraphPose], fps: float,
                          mesh_id: int = 0) -> None:
    """Write `poses` (one per frame at `fps`) as concatenated transform blocks."""
    with open(path, "wb") as f:
        for k, pose in enumerate(poses):
            t = 1000.0 * k / fps
            f.write(pack_transforms(k, mesh_id, pose.node_matrices(graph.nodes), t, t))


def read_take_transforms(path: str | Path) -> np.ndarray:
    """(frames, N, 4, 4) float32 node matrices from `write_take_transforms` output."""
    data = Path(path).read_bytes()
    frames, offset = [], 0
    while offset < len(data):
        if len(data) - offset < HEADER.size:
            raise BadMotionError(f"{path}: {len(data) - offset} stray bytes after frame {len(frames)}")
        n = HEADER.unpack_from(data, offset)[3]
        size = block_size(n)
        try:
            frames.append(unpack_transforms(data[offset:offset + size])[4])
        except TransformBlockError:
            raise BadMotionError(f"{path}: frame {len(frames)} is not a transform block") from None
        offset += size
    if not frames:
        raise BadMotionError(f"{path}: no frames")
    return np.stack(frames)
