"""affine_inverse against the definition: a stack of affine matrices times its inverses is the identity, and a
rigid motion's inverse is its transpose-and-back-translation by hand."""
import numpy as np

from kinetre.affine import affine_inverse
from kinetre.rotation import axis_rotations


def test_a_rigid_motion_is_undone_by_its_transpose_and_back_translation():
    m = np.eye(4)
    m[:3, :3] = axis_rotations(1, np.array([30.0]))[0]
    m[:3, 3] = [1.0, -2.0, 0.5]
    expected = np.eye(4)
    expected[:3, :3] = m[:3, :3].T
    expected[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    np.testing.assert_allclose(affine_inverse(m), expected, rtol=0, atol=1e-15)


def test_a_stack_of_scaled_sheared_transforms_times_its_inverses_is_the_identity():
    rng = np.random.default_rng(7)
    m = np.zeros((5, 7, 4, 4))
    m[..., :3, :3] = rng.normal(size=(5, 7, 3, 3)) + 3.0 * np.eye(3)  # well conditioned, with scale and shear
    m[..., :3, 3] = rng.normal(size=(5, 7, 3))
    m[..., 3, 3] = 1.0
    inverse = affine_inverse(m)
    np.testing.assert_allclose(inverse @ m, np.broadcast_to(np.eye(4), m.shape), rtol=0, atol=1e-12)
    np.testing.assert_allclose(inverse, np.linalg.inv(m), rtol=1e-10, atol=1e-12)
