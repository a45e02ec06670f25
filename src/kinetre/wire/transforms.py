"""The node-transform block: a graph pose as the scene publishes it and a take stores it.

One block per pose, little-endian:

    offset 0   4s   b"KTX1"
    offset 4   u32  seq (frame number)
    offset 8   u32  mesh id (a page drops blocks for a mesh it has not loaded yet)
    offset 12  u32  N nodes
    offset 16  f64  t_source: timestamp (ms) of the newest skeleton frame the solve used
    offset 24  f64  t_out: time (ms) when the block was published
    offset 32  f32  N × 12: the top three rows of each node matrix (pose.node_matrices), row-major

The page reads the same layout (web/src/net/protocol.ts).
"""
from __future__ import annotations

import struct

import numpy as np

MAGIC = b"KTX1"
HEADER = struct.Struct("<4sIIIdd")
NODE_BYTES = 48  # 12 float32 per node


class TransformBlockError(ValueError):
    """Bytes that are not one transform block (wrong magic or length)."""


def block_size(nodes: int) -> int:
    return HEADER.size + NODE_BYTES * nodes


def pack_transforms(seq: int, mesh_id: int, matrices: np.ndarray, t_source: float, t_out: float) -> bytes:
    """Binary block for (N, 4, 4) node matrices (see the module docstring)."""
    n = matrices.shape[0]
    body = np.ascontiguousarray(matrices[:, :3, :], dtype="<f4").tobytes()
    return HEADER.pack(MAGIC, seq & 0xFFFFFFFF, mesh_id, n, t_source, t_out) + body


def unpack_transforms(block: bytes) -> tuple[int, int, float, float, np.ndarray]:
    """(seq, mesh_id, t_source, t_out, (N, 4, 4) float32) from `pack_transforms` output."""
    if len(block) < HEADER.size:
        raise TransformBlockError("not a transform block")
    magic, seq, mesh_id, n, t_source, t_out = HEADER.unpack_from(block)
    if magic != MAGIC or len(block) != block_size(n):
        raise TransformBlockError("not a transform block")
    m = np.zeros((n, 4, 4), np.float32)
    m[:, :3, :] = np.frombuffer(block, "<f4", offset=HEADER.size).reshape(n, 3, 4)
    m[:, 3, 3] = 1.0
    return seq, mesh_id, t_source, t_out, m
