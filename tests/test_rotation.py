"""The rotation helpers every stage shares: quaternions to matrices and back, slerp, minimal rotations, the
quarter turns of an up axis."""
from __future__ import annotations

import doctest

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kinetre.rotation
from kinetre.rotation import (axis_rotations, matrix_quaternions, minimal_rotation_into, minimal_rotations,
                              quaternion_matrices, slerp, up_rotation)


def test_docstring_examples():
    result = doctest.testmod(kinetre.rotation, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted >= 5 and result.failed == 0


def test_quaternions_and_matrices_agree_with_scipy_both_ways():
    r = Rotation.random(50, random_state=3)
    q = r.as_quat()
    np.testing.assert_allclose(quaternion_matrices(q), r.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(quaternion_matrices(3.0 * q.reshape(5, 10, 4)), r.as_matrix().reshape(5, 10, 3, 3),
                               atol=1e-12)                  # any leading shape, not normalised
    back = matrix_quaternions(r.as_matrix().reshape(10, 5, 3, 3)).reshape(50, 4)
    np.testing.assert_allclose(np.abs(np.einsum("ni,ni->n", back, q)), 1.0, atol=1e-12)   # q or -q


def test_slerp_keeps_a_uniform_angle_on_the_short_arc():
    a = np.array([[0.0, 0.0, 0.0, 1.0]])
    b = -Rotation.from_euler("y", 90, degrees=True).as_quat()[None]       # the long way round as given
    for u in (0.25, 0.5, 1.0):
        angle = Rotation.from_quat(slerp(a, b, np.array([u]))).magnitude()[0]
        assert angle == pytest.approx(np.radians(90) * u)


def test_minimal_rotations_turn_u_onto_v_by_the_smallest_angle():
    rng = np.random.default_rng(0)
    u, v = rng.normal(size=(20, 3)), rng.normal(size=(20, 3))
    r = minimal_rotations(u, v)
    un, vn = u / np.linalg.norm(u, axis=1)[:, None], v / np.linalg.norm(v, axis=1)[:, None]
    np.testing.assert_allclose(np.einsum("nij,nj->ni", r, un), vn, atol=1e-12)
    np.testing.assert_allclose(r @ r.transpose(0, 2, 1), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
    angle = Rotation.from_matrix(r).magnitude()
    np.testing.assert_allclose(angle, np.arccos(np.clip(np.einsum("ni,ni->n", un, vn), -1, 1)), atol=1e-9)
    for axis in np.eye(3):                                    # opposite: a half turn that still lands on v
        flip = minimal_rotations(axis, -axis)
        np.testing.assert_allclose(flip @ axis, -axis, atol=1e-12)
        assert np.linalg.det(flip) == pytest.approx(1.0)


def test_axis_and_up_rotations_are_proper():
    r = axis_rotations(1, np.array([30.0, -120.0]))
    np.testing.assert_allclose(r, Rotation.from_euler("y", [[30.0], [-120.0]], degrees=True).as_matrix(), atol=1e-12)
    for up in np.concatenate([np.eye(3), -np.eye(3)]):
        turn = up_rotation(up)
        np.testing.assert_allclose(turn @ up, [0, 1, 0], atol=1e-12)
        assert np.linalg.det(turn) == pytest.approx(1.0)


def test_the_compiled_minimal_rotation_maps_and_handles_opposites_like_the_array_one():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((50, 3))
    b = rng.standard_normal((50, 3))
    a /= np.linalg.norm(a, axis=1)[:, None]
    b /= np.linalg.norm(b, axis=1)[:, None]
    u, v = np.vstack([a, a[:1], a[1:2]]), np.vstack([b, -a[:1], a[1:2]])
    r = np.empty((len(u), 3, 3))
    for i in range(len(u)):
        minimal_rotation_into(u[i], v[i], r[i])
    assert np.allclose(r, minimal_rotations(u, v))
    assert np.allclose(np.einsum("nij,nj->ni", r, u), v)
    assert np.allclose(np.linalg.det(r), 1.0)
