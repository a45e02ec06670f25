"""Pieces of a mesh that move as one bone: a robot's forearm, a truck's wheel.

A separate piece of the mesh (`DeformationGraph.pieces`) whose bone samples nearly all come from one bone
is an artist's rigid part: its nodes take that bone's rigid motion (its rotation, the source's own where
the source carries bone frames, about its parent joint) instead of the solve's, so the piece neither bends
nor shears, however far it reaches beyond the bone (a big head above a short neck).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .attach import SkeletonAttachment, bone_rotations, framed_rotations
from .models import Skeleton

SHARE = 0.9  # of a piece's bone samples from one bone, for the piece to follow that bone rigidly
MIN_SAMPLES = 4  # bone samples a piece needs before it is judged


@dataclass(frozen=True, eq=False)
class RigidPiece:
    """nodes : (n,) int64 the piece's graph nodes; skeleton : index of the attachment; bone : its bone row."""

    nodes: np.ndarray
    skeleton: int
    bone: int


def rigid_pieces(pieces: np.ndarray | None, attachments: tuple[SkeletonAttachment, ...]) -> tuple[RigidPiece, ...]:
    """The pieces of the graph (`pieces`: per node its piece, or None) that follow one bone rigidly."""
    if pieces is None or len(np.unique(pieces)) < 2:
        return ()
    votes: dict[int, dict[tuple[int, int], int]] = {}
    for s, att in enumerate(attachments):
        carrier = att.constraints.nodes[np.arange(len(att.bone)), np.argmax(att.constraints.weights, axis=1)]
        for node, bone in zip(carrier[att.bone >= 0], att.bone[att.bone >= 0]):
            tally = votes.setdefault(int(pieces[node]), {})
            tally[(s, int(bone))] = tally.get((s, int(bone)), 0) + 1
    out = []
    for piece, tally in votes.items():
        total = sum(tally.values())
        (s, bone), top = max(tally.items(), key=lambda kv: kv[1])
        if total >= MIN_SAMPLES and top >= SHARE * total:
            out.append(RigidPiece(np.flatnonzero(pieces == piece), s, bone))
    return tuple(out)


def hold_rigid(x: np.ndarray, nodes: np.ndarray, pieces: tuple[RigidPiece, ...],
               attachments: tuple[SkeletonAttachment, ...], frames: list[Skeleton]) -> np.ndarray:
    """The graph state x (N, 12: row-major A, then t) with every rigid piece's nodes moved by its bone:
    A = R, t = R g + T - g for the bone's motion x -> R x + T (Eq. 2 then moves the piece rigidly). A piece
    whose bone is not tracked keeps the solve's."""
    out = x.copy()
    rotations: dict[int, np.ndarray] = {}
    for piece in pieces:
        att, frame = attachments[piece.skeleton], frames[piece.skeleton]
        p, c = att.bind.model.bones[piece.bone]
        if not (frame.tracked[p] and frame.tracked[c]):
            continue
        if piece.skeleton not in rotations:
            rotations[piece.skeleton] = framed_rotations(att.bind, frame,
                                                         bone_rotations(att.bind, frame, att.twist_reference))
        r = rotations[piece.skeleton][piece.bone]
        shift = frame.positions[p] - r @ att.bind.positions[p]
        g = nodes[piece.nodes]
        out[piece.nodes, :9] = r.reshape(9)
        out[piece.nodes, 9:] = g @ r.T + shift - g
    return out
