"""Algorithm 2 on the shared face photos and on synthetic poses of the template."""
from __future__ import annotations

import numpy as np
import pytest

from kinetre.face.align import align
from kinetre.face.caricature import NAMES, PRESETS, falloff, morph_targets, weights_from
from kinetre.face.reconstruct import CM, Anchor, reconstruct
from kinetre.face.template import load_template


def _rotation(yaw=0.0, pitch=0.0, roll=0.0):
    a, b, c = np.radians([yaw, pitch, roll])
    ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return rz @ rx @ ry


def _angle(a, b):
    return np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1)))


def _image_landmarks(rotation, scale=14.0, offset=(410.0, 400.0)):
    """The template seen by an orthographic camera: pixels (x right, y down, z into the scene)."""
    p = scale * load_template().vertices @ rotation.T
    return np.c_[p[:, 0] + offset[0], offset[1] - p[:, 1], -p[:, 2]]


@pytest.mark.parametrize("depth", [True, False], ids=["with-depth", "2d-only"])
def test_synthetic_30_degree_yaw_is_undone(depth):
    truth = _rotation(yaw=30.0, pitch=8.0, roll=-5.0)
    lm = _image_landmarks(truth)
    frame = reconstruct(lm if depth else lm[:, :2], 820, 1024)
    assert _angle(frame.pose.rotation, truth) < 2.0
    # the aligned face is the frontal template: nothing of the 30° turn is left in the vertices
    t = load_template()
    expected = t.vertices - t.vertices[t.chin]
    assert np.abs(frame.face - frame.face[t.chin] - expected).max() < 0.05            # cm
    assert np.abs(frame.vertices - frame.anchor.position - CM * expected).max() < 5e-4  # m


def test_noisy_yaw_within_two_degrees():
    rng = np.random.default_rng(0)
    truth = _rotation(yaw=30.0)
    lm = _image_landmarks(truth) + rng.normal(0, 1.0, (468, 3))     # 1 px noise on a 14 px/cm face
    assert _angle(align(lm * [1, -1, -1], load_template().vertices, load_template().weights).rotation, truth) < 2.0
    assert _angle(reconstruct(lm[:, :2], 820, 1024).pose.rotation, truth) < 2.0


@pytest.mark.parametrize("name", ["face_frontal_portrait.jpg", "face_business_person.png"])
def test_real_faces_keep_topology_and_project_onto_their_landmarks(photos, name):
    image, lm = photos[name]
    h, w = image.shape[:2]
    for turn in (False, True):
        frame = reconstruct(lm, w, h, turn=turn)
        assert frame.vertices.shape == (468, 3) and np.isfinite(frame.vertices).all()
        assert np.abs(frame.project() - lm[:, :2]).max() < 2.0                    # pixels
        assert np.allclose(frame.uvs * [w, h], lm[:, :2])                           # live texture coordinates
    # the face is face-sized and upright: ~15 cm wide, chin lowest, nose tip in front
    t = load_template()
    size = np.ptp(frame.vertices, axis=0)
    assert 0.10 < size[0] < 0.20 and 0.12 < size[1] < 0.24
    flat = reconstruct(lm, w, h)
    assert flat.vertices[t.chin, 1] == pytest.approx(flat.vertices[:, 1].min(), abs=0.01)
    assert flat.vertices[t.nose_tip, 2] > np.median(flat.vertices[:, 2])


def test_chin_sits_on_the_anchor(photos):
    image, lm = photos["face_frontal_portrait.jpg"]
    neck = Anchor(position=np.array([0.1, 1.5, -0.2]), rotation=_rotation(yaw=90.0))
    frame = reconstruct(lm, image.shape[1], image.shape[0], anchor=neck)
    t = load_template()
    assert np.allclose(frame.vertices[t.chin], neck.position)
    # facing along the neck's +z (turned 90° about y: towards +x)
    assert frame.vertices[t.nose_tip, 0] - neck.position[0] > 0.03
    assert np.abs(frame.project() - lm[:, :2]).max() < 2.0


def test_caricatures_are_zero_at_weight_zero_and_local(photos):
    image, lm = photos["face_business_person.png"]
    h, w = image.shape[:2]
    morphs = morph_targets()
    assert morphs.shape == (len(NAMES), 468, 3)
    plain = reconstruct(lm, w, h)
    zero = reconstruct(lm, w, h, morphs=morphs, weights=np.zeros(len(NAMES)))
    assert np.array_equal(plain.vertices, zero.vertices)
    t = load_template()
    for k, name in enumerate(NAMES):
        moved = np.linalg.norm(morphs[k], axis=1)
        assert moved.max() > 0.2, name                                  # each morph does something (cm)
        assert (moved < 1e-9).sum() > 100, name                         # ... to a region, not the whole face
        one = reconstruct(lm, w, h, morphs=morphs, weights=np.eye(len(NAMES))[k])
        assert np.allclose(one.vertices - plain.vertices, CM * (morphs[k] - morphs[k][t.chin]))
    # eyes grow, the jaw widens, the forehead rises
    eyes, jaw, forehead = (NAMES.index(n) for n in ("eyes", "jaw", "forehead"))
    assert np.ptp((t.vertices + morphs[eyes])[[33, 133], 0]) > np.ptp(t.vertices[[33, 133], 0])
    assert np.ptp((t.vertices + morphs[jaw])[[172, 397], 0]) > 1.1 * np.ptp(t.vertices[[172, 397], 0])
    assert morphs[forehead][10, 1] > 1.0
    for preset in PRESETS.values():
        assert weights_from(preset).shape == (len(NAMES),)
    with pytest.raises(ValueError, match="ears"):
        weights_from({"ears": 1.0})


def test_falloff_is_smooth_at_the_rim():
    r = 2.0
    d = np.array([0.0, r - 1e-4, r, r + 1.0])
    phi = falloff(d, r)
    assert phi[0] == 1.0 and phi[1] < 1e-7 and phi[2] == 0.0 and phi[3] == 0.0
    slope = (falloff(np.array([r - 1e-6]), r) - 0.0) / 1e-6
    assert abs(slope[0]) < 1e-4                                         # C¹: no crease at the region's edge


def test_bad_landmarks_are_refused():
    from kinetre.errors import BadFaceError
    with pytest.raises(BadFaceError, match="expected"):
        reconstruct(np.zeros((10, 2)), 100, 100)
    lm = _image_landmarks(np.eye(3))
    lm[5, 0] = np.nan
    with pytest.raises(BadFaceError, match="non-finite"):
        reconstruct(lm, 820, 1024)
    with pytest.raises(BadFaceError, match="turned too far"):
        reconstruct(_image_landmarks(_rotation(yaw=89.0)), 820, 1024)
