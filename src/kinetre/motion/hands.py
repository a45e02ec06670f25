"""A take's hand as a skeleton of its own: MediaPipe's 21 hand landmarks (`HAND21`: the wrist, four joints per
finger) drive a mesh as any skeleton does, so a hand can walk a spider, a table or a sock puppet (a hand
puppet).

Takes from `kinetre capture` record each person's hands in metres (MediaPipe's hand world landmarks, the
wrist at the body's wrist: docs/take-format.md). A hand whose length, wrist to middle fingertip along the
finger, is not a real hand's (`REAL`: normalised image coordinates, pixels, a file's other units) is scaled
to `HAND_LENGTH`; a hand in metres keeps its own size. Since a hand is placed in a mesh from the two shapes
(`align.fit_shapes`), its size sets no size of the mesh, only of what `--fit` resizes the mesh to.

A hand is a limb with fingers for legs: `hang_rotation` turns a hand whose fingertips do not already hang below
its palm (a hand held up to a webcam) over so they do, and the shape fit then finds the turn about +Y that
puts the fingers in the mesh's legs.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import BadMotionError
from ..mesh.mesh import Mesh
from ..rotation import minimal_rotations
from ..skeleton.models import FINGER_JOINTS, HAND21, Skeleton
from .align import ShapeFit, fit_shapes
from .take import Take

SIDES = ("left", "right")  # the order of `Take.hands`' hands
HAND_LENGTH = 0.18  # metres, wrist to middle fingertip along the finger: an adult's hand
REAL = (0.10, 0.30)  # metres: hand lengths taken as recorded in metres (a child's hand to a large one)
HANGS = 60.0  # degrees: fingertips this near straight below the palm already hang (a spider's splayed legs)

_MIDDLE = [0] + [HAND21.index(j) for j in FINGER_JOINTS["middle"]]
_BASES = [0] + [HAND21.index(chain[0]) for chain in FINGER_JOINTS.values()]
_TIPS = [HAND21.index(chain[-1]) for chain in FINGER_JOINTS.values()]


def hand_length(hands: np.ndarray) -> float:
    """The median length, wrist to middle fingertip along the finger (so a bent finger is as long as a
    straight one), of the hands (..., 21, 3) that are seen; NaN when none is."""
    chain = np.asarray(hands, dtype=np.float64).reshape(-1, 21, 3)[:, _MIDDLE]
    lengths = np.linalg.norm(np.diff(chain, axis=1), axis=2).sum(axis=1)
    lengths = lengths[np.isfinite(lengths)]
    return float(np.median(lengths)) if lengths.size else float("nan")


def real_size(hands: np.ndarray) -> np.ndarray:
    """The hands (T, 21, 3) at a real hand's size: unchanged when their length lies in `REAL`, else scaled
    about the first seen wrist to `HAND_LENGTH` (their travel scaled with them)."""
    hands = np.asarray(hands, dtype=np.float64)
    length = hand_length(hands)
    if not np.isfinite(length) or REAL[0] <= length <= REAL[1] or length <= 0:
        return hands
    seen = np.isfinite(hands).all(axis=(1, 2))
    wrist = hands[np.argmax(seen), 0]
    return wrist + (hands - wrist) * (HAND_LENGTH / length)


def hand_take(take: Take, side: str, person: int | None = None, where: str | None = None) -> Take:
    """The `side` ("left" or "right") hand of a camera take's person (default: the main person) as a take of
    `HAND21` skeletons, at a real hand's size (`real_size`); frames where the hand is not seen are untracked.
    `where` names the take in errors (default: its source).

    Raises
    ------
    BadMotionError
        The side is not left or right, the take records no hands, has no such person, or the hand is not
        seen in any frame; each message names the take's file.
    """
    where = where or take.source or "take"
    if side not in SIDES:
        raise BadMotionError(f"{where}: a hand is left or right, got {side!r}")
    if take.hands is None:
        raise BadMotionError(f"{where}: records no hands (record the take with `kinetre capture`, without "
                             f"--no-hands)")
    if person is None:
        hands, who = take.main_hands()[:, SIDES.index(side)], "the main person"
    else:
        if person not in take.people:
            raise BadMotionError(f"{where}: no person {person} (the take has {list(take.people)})")
        hands, who = take.person(person).hands[:, 0, SIDES.index(side)], f"person {person}"
    seen = np.isfinite(hands).all(axis=(1, 2))
    if not seen.any():
        raise BadMotionError(f"{where}: the {side} hand of {who} is not seen in any of its {len(take)} frames")
    return Take(HAND21, real_size(hands), np.repeat(seen[:, None], 21, axis=1), take.fps, take.source)


def first_seen(take: Take) -> int:
    """The first frame of a take that tracks any joint (-1 when none does)."""
    seen = take.tracked.any(axis=1)
    return int(np.argmax(seen)) if seen.any() else -1


def hang_rotation(frame: Skeleton) -> np.ndarray:
    """(3, 3) the identity when a hand's fingertips hang below its palm (the wrist and the five finger bases:
    within `HANGS` of straight down), else the smallest turn that puts them straight below it; the identity
    too when the frame is no hand or does not track them."""
    if frame.model.name != HAND21.name or not (frame.tracked[_BASES].all() and frame.tracked[_TIPS].all()):
        return np.eye(3)
    down = frame.positions[_TIPS].mean(axis=0) - frame.positions[_BASES].mean(axis=0)
    length = float(np.linalg.norm(down))
    if not length > 1e-12 or -down[1] / length >= np.cos(np.radians(HANGS)):
        return np.eye(3)
    return minimal_rotations(down, np.array([0.0, -1.0, 0.0]))


def fit_hand(take: Take, mesh: Mesh, bind_frame: int = 0, hang: bool = True, **options) -> ShapeFit:
    """`align.fit_shapes` for a hand: turned over first (`hang_rotation` of the bind frame) unless `hang` is
    False; the placement's rotation includes that turn. `options` go to `fit_shapes` (fit, yaw, flip,
    fit_mesh, nodes)."""
    turn = hang_rotation(take.frame(bind_frame)) if hang else np.eye(3)
    shape = fit_shapes(take.transformed(1.0, turn), mesh, bind_frame, **options)
    return replace(shape, placement=replace(shape.placement, rotation=shape.placement.rotation @ turn))


@dataclass(frozen=True, eq=False)
class HandPuppet:
    """A live hand put inside a mesh, in the mesh's own frame and units (`fit_puppet`).

    Attributes
    ----------
    scale, rotation (3, 3), translation (3,) : a hand frame x goes to scale * rotation @ x + translation
    metre : the mesh-frame length of a metre of the fit's solve frame, where the mesh's longest side is a
        person's height: attachment's reach (10 cm) and bone radius (4 cm) are that many times as long here
    """

    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    metre: float

    def place(self, hand: Skeleton) -> Skeleton:
        return hand.transformed(self.scale, self.rotation, self.translation)


def fit_puppet(hand: Skeleton, mesh: Mesh, nodes: np.ndarray | None = None, hang: bool = True) -> HandPuppet:
    """One hand frame (a live user's, at possession) put inside `mesh` as `fit_hand` places a take's bind
    frame. `nodes`: the mesh's graph nodes (see `align.fit_shapes`)."""
    one = Take(HAND21, hand.positions[None], hand.tracked[None], 1.0, "hand")
    placement = fit_hand(one, mesh, 0, hang, nodes=nodes).placement
    k = placement.mesh_scale  # the solve frame is the mesh scaled by k
    return HandPuppet(placement.skeleton_scale / k, placement.rotation, placement.translation / k, 1.0 / k)
