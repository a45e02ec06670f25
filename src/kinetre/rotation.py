"""Rotations, written once: unit quaternions (glTF order x, y, z, w) to and from matrices, their spherical
interpolation, the minimal rotation between two directions, and the quarter turns that stand a file upright.
Every stage (motion files, avatars, exports, VMC) uses these."""
from __future__ import annotations

import numpy as np

from .jit import njit


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


def axis_rotations(axis: int, degrees: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations by `degrees` (...) about coordinate axis 0, 1 or 2 (right-handed).

    >>> np.round(axis_rotations(2, np.array([90.0]))[0] @ [1, 0, 0], 12)
    array([0., 1., 0.])
    """
    a = np.radians(np.asarray(degrees, dtype=np.float64))
    c, s = np.cos(a), np.sin(a)
    r = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r[..., axis, axis] = 1.0
    r[..., i, i] = c
    r[..., j, j] = c
    r[..., i, j] = -s
    r[..., j, i] = s
    return r


def quaternion_matrices(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of (..., 4) quaternions (x, y, z, w), normalised first.

    >>> np.round(quaternion_matrices(np.array([0.0, 0.0, 1.0, 1.0])) @ [1, 0, 0], 12)
    array([0., 1., 0.])
    """
    q = np.asarray(q, dtype=np.float64)
    q = q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-300)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def matrix_quaternions(rotations: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (x, y, z, w) of (..., 3, 3) rotation matrices: scipy's
    `Rotation.from_matrix(...).as_quat()`, bit for bit, by one kernel pass when every matrix is a rotation to
    within rounding (as the polar and SVD factors of a take, or a live frame's bones, are).

    scipy first tests every matrix (a positive determinant, M Mᵀ within 1e-12 of the identity), re-orthogonalises
    those that fail, then converts each with Shepperd's method. The kernel converts with the same arithmetic in
    the same order, so where its own, stricter test passes for all (off-diagonal |M Mᵀ| ≤ 1e-13, diagonal within
    1e-6 of 1, determinant above 1/2: scipy's test passes too, whatever the rounding of M Mᵀ) the quaternions are
    scipy's; any other input goes to scipy. For many matrices the test and the object-per-call conversion were
    most of scipy's time.

    >>> matrix_quaternions(np.eye(3))
    array([0., 0., 0., 1.])
    """
    r = np.ascontiguousarray(rotations, dtype=np.float64)
    flat = r.reshape(-1, 3, 3)
    out = np.empty((len(flat), 4))
    if not _shepperd(flat, out):
        from scipy.spatial.transform import Rotation
        out = Rotation.from_matrix(flat).as_quat()
    return out.reshape(r.shape[:-2] + (4,))


@njit(cache=True)
def _shepperd(m, q):
    """scipy's `_from_matrix_orthogonal` (Shepperd's method, then the quaternion divided by its norm) for rotation
    matrices `m` (n, 3, 3) into `q` (n, 4); False, with `q` unfinished, when a matrix is not a rotation to within
    the margins of `matrix_quaternions`."""
    for n in range(m.shape[0]):
        a = m[n]
        det = (a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]) - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
               + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]))
        if not det > 0.5:
            return False
        for i in range(3):
            for j in range(3):
                g = a[i, 0] * a[j, 0] + a[i, 1] * a[j, 1] + a[i, 2] * a[j, 2]
                if not (abs(g - 1.0) <= 1e-6 if i == j else abs(g) <= 1e-13):
                    return False
        trace = a[0, 0] + a[1, 1] + a[2, 2]
        choice, best = 0, a[0, 0]  # the first largest of the diagonal and the trace
        if a[1, 1] > best:
            choice, best = 1, a[1, 1]
        if a[2, 2] > best:
            choice, best = 2, a[2, 2]
        if trace > best:
            choice = 3
        if choice != 3:
            i = choice
            j = (i + 1) % 3
            k = (j + 1) % 3
            q[n, i] = 1 - trace + 2 * a[i, i]
            q[n, j] = a[j, i] + a[i, j]
            q[n, k] = a[k, i] + a[i, k]
            q[n, 3] = a[k, j] - a[j, k]
        else:
            q[n, 0] = a[2, 1] - a[1, 2]
            q[n, 1] = a[0, 2] - a[2, 0]
            q[n, 2] = a[1, 0] - a[0, 1]
            q[n, 3] = 1 + trace
        norm = np.sqrt(q[n, 0] * q[n, 0] + q[n, 1] * q[n, 1] + q[n, 2] * q[n, 2] + q[n, 3] * q[n, 3])
        for c in range(4):
            q[n, c] /= norm
    return True




def slerp(a: np.ndarray, b: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(N, 4) unit quaternions on the shortest arc from a (N, 4) to b (N, 4) at fractions u (N,)."""
    dot = np.einsum("ni,ni->n", a, b)
    b = np.where(dot[:, None] < 0, -b, b)
    dot = np.abs(dot)
    th = np.arccos(np.clip(dot, -1.0, 1.0))
    s = np.sin(th)
    near = s < 1e-6  # nearly equal: the linear blend is exact to rounding
    wa = np.where(near, 1 - u, np.sin((1 - u) * th) / np.where(near, 1.0, s))
    wb = np.where(near, u, np.sin(u * th) / np.where(near, 1.0, s))
    q = wa[:, None] * a + wb[:, None] * b
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def minimal_rotations(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) smallest rotations turning directions u (..., 3) onto v (..., 3) (Rodrigues); half a turn
    about an axis perpendicular to u where they are opposite.

    >>> np.round(minimal_rotations(np.array([1.0, 0, 0]), np.array([0, 2.0, 0])) @ [1, 0, 0], 12)
    array([0., 1., 0.])
    """
    u, v = np.broadcast_arrays(np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64))
    shape = u.shape[:-1]
    u, v = u.reshape(-1, 3), v.reshape(-1, 3)
    u = u / np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    v = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
    axis = np.cross(u, v)
    s2 = np.einsum("fi,fi->f", axis, axis)
    c = np.einsum("fi,fi->f", u, v)
    k = np.zeros((len(u), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = axis[:, 2], -axis[:, 1], axis[:, 0]
    scale = np.where(s2 > 1e-24, (1.0 - c) / np.maximum(s2, 1e-24), 0.5)
    rot = np.eye(3) + k + scale[:, None, None] * (k @ k)
    flip = (s2 <= 1e-24) & (c < 0)
    if flip.any():
        perp = np.cross(u[flip], [1.0, 0.0, 0.0])
        weak = np.linalg.norm(perp, axis=1) < 1e-6
        perp[weak] = np.cross(u[flip][weak], [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp, axis=1, keepdims=True)
        rot[flip] = 2 * np.einsum("fi,fj->fij", perp, perp) - np.eye(3)
    return rot.reshape(shape + (3, 3))


@njit(cache=True)
def minimal_rotation_into(a, b, out):
    """`minimal_rotations` for one pair of unit vectors a, b into out (3, 3), for compiled per-bone loops
    (scalar arithmetic: there small temporary arrays cost more than the maths)."""
    v0 = a[1] * b[2] - a[2] * b[1]
    v1 = a[2] * b[0] - a[0] * b[2]
    v2 = a[0] * b[1] - a[1] * b[0]
    c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    s2 = v0 * v0 + v1 * v1 + v2 * v2
    if c < -1 + 1e-12 and s2 <= 1e-24:  # opposite: a half turn about an axis perpendicular to a
        h0, h1 = (1.0, 0.0) if abs(a[0]) < 0.9 else (0.0, 1.0)
        u0, u1, u2 = -a[2] * h1, a[2] * h0, a[0] * h1 - a[1] * h0  # a × (h0, h1, 0)
        n = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        u = (u0 / n, u1 / n, u2 / n)
        for i in range(3):
            for j in range(3):
                out[i, j] = 2.0 * u[i] * u[j] - (1.0 if i == j else 0.0)
        return
    f = (1 - c) / s2 if s2 > 1e-24 else 0.5
    # I + [v]× + f [v]×², with [v]×² = v vᵀ − s2 I
    v = (v0, v1, v2)
    for i in range(3):
        for j in range(3):
            out[i, j] = f * v[i] * v[j] + ((1.0 - f * s2) if i == j else 0.0)
    out[0, 1] -= v2
    out[0, 2] += v1
    out[1, 0] += v2
    out[1, 2] -= v0
    out[2, 0] -= v1
    out[2, 1] += v0


def rotation_part(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the rotation of each (..., 3, 3) linear map (its polar factor: scale and shear removed)."""
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    flip = np.linalg.det(r) < 0  # a mirroring scale: keep a proper rotation
    if flip.any():
        u = u.copy()
        u[flip, :, 2] *= -1.0
        r = np.where(flip[..., None, None], u @ vt, r)
    return r
