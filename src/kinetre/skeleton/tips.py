"""Where a childless joint's part ends: a tip joint at the part's skinned centre.

A last joint (a head, a hand without fingers, a game rig's one-bone arm) turns the part it carries, but no
bone of the joints shows which way the part points. The skin does: the skin-weighted centre of the
vertices the joint moves. Where that centre lies off the joint (by more than a tenth of the bone into it),
a tip there, carried by the joint, makes the part a bone. Motion files (`kinetre.motion.gltf`) and avatars
(`kinetre.avatar.bonemap`) add the same tips, so the skeleton mapper gives both the same answer.
"""
from __future__ import annotations

import numpy as np

from .humanoid_map import name_tokens

SHARE = 0.1  # of the bone into a joint, for its part's centre to lie off it
SOCKETS = {"socket", "attach", "attachment", "prop", "weapon", "slot", "mount"}


def is_socket(name: str) -> bool:
    """A joint named as a place props attach to ("socket_hand_L", "WeaponSlot").

    >>> is_socket("socket_hand_L"), is_socket("hand_L")
    (True, False)
    """
    return bool(SOCKETS & set(name_tokens(name)))


def part_tips(names, parents, rest: np.ndarray, centres: dict) -> list[tuple[int, str, np.ndarray]]:
    """(joint, tip name, tip position (3,)) for every joint with a parent and no child joints but childless
    sockets (`is_socket`) whose part's centre (`centres`: joint -> (3,)
    world position in the rest pose) lies off it.

    >>> part_tips(["hip", "arm"], [-1, 0], np.array([[0, 1, 0], [0.2, 1.4, 0]]), {1: np.array([0.25, 1.1, 0])})
    [(1, 'arm.tip', array([0.25, 1.1 , 0.  ]))]
    """
    rest = np.asarray(rest, dtype=np.float64)
    # a socket below a joint (a childless joint where a prop attaches) is no continuation of its part
    has_child = {int(q) for q in parents}
    has_child = {int(q) for k, q in enumerate(parents) if k in has_child or not is_socket(names[k])}
    taken = set(names)
    out = []
    for k, q in enumerate(parents):
        if k in has_child or k not in centres or q < 0:
            continue
        bone = np.linalg.norm(rest[k] - rest[q])
        c = np.asarray(centres[k], dtype=np.float64)
        if not np.linalg.norm(c - rest[k]) > SHARE * bone:
            continue
        name, n = f"{names[k]}.tip", 2
        while name in taken:
            name, n = f"{names[k]}.tip{n}", n + 1
        taken.add(name)
        out.append((k, name, c))
    return out


def part_end(centre: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """From a joint (the origin of its bind frame) towards its part's `centre`, as far as `vertices` reach
    along that line (the centre when none does)."""
    n = np.linalg.norm(centre)
    if n < 1e-12 or not len(vertices):
        return centre
    reach = float((vertices @ (centre / n)).max())
    return centre * max(reach, n) / n
