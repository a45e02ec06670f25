"""Rotations, written once: unit quaternions (glTF order x, y, z, w) to and from matrices, their spherical
interpolation, the minimal rotation between two directions, and the quarter turns that stand a file upright.
Every stage (motion files, avatars, exports, VMC) uses these."""
from __future__ import annotations

import numpy as np


def up_rotation(up: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking the signed coordinate axis nearest `up` to +Y (identity for +Y).

    >>> up_rotation(np.array([0.1, 0.0, 2.0])) @ [0, 0, 1]
    array([0., 1., 0.])
    """
    up = np.asarray(up, dtype=np.float64)
    axis = int(np.argmax(np.abs(up)))
    e = np.zeros(3)
    e[axis] = np.sign(up[axis])
    if e[1] == 1.0:
        return np.eye(3)
    if e[1] == -1.0:  # upside down: half a turn about X
        return np.diag([1.0, -1.0, -1.0])
    k = np.cross(e, [0.0, 1.0, 0.0])  # quarter turn about e x Y (Rodrigues with sin 1, cos 0)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + kx + kx @ kx
