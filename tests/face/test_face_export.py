"""`kinetre face`: photos and a video to validator-clean, textured glTF with caricature morph targets."""
from __future__ import annotations

import cv2
import numpy as np
import pygltflib as gl
import pytest

from export.takes import validate_gltf
from kinetre.cli import main
from kinetre.face.caricature import NAMES, morph_targets
from kinetre.face.reconstruct import CM, reconstruct
from kinetre.face.template import load_template


def _accessor(doc, blob, index):
    acc = doc.accessors[index]
    view = doc.bufferViews[acc.bufferView]
    dtype = {gl.FLOAT: "<f4", gl.UNSIGNED_SHORT: "<u2", gl.UNSIGNED_INT: "<u4"}[acc.componentType]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[acc.type]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    return np.frombuffer(blob, dtype, acc.count * width, start).reshape(acc.count, width)


def _clean(report):
    issues = report["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:5]


@pytest.mark.parametrize("name", ["face_frontal_portrait.jpg", "face_business_person.png"])
def test_photo_to_glb(data_dir, photos, tmp_path, name, capsys):
    out = tmp_path / "face.glb"
    assert main(["face", str(data_dir / "images" / "face" / name), "-o", str(out), "--morph", "eyes=0.5"]) == 0
    _clean(validate_gltf(out))
    doc = gl.GLTF2().load(str(out))
    blob = doc.binary_blob()
    prim = doc.meshes[0].primitives[0]
    image, lm = photos[name]
    h, w = image.shape[:2]
    frame = reconstruct(lm, w, h)
    assert np.abs(_accessor(doc, blob, prim.attributes.POSITION) - frame.vertices).max() < 1e-5
    assert np.abs(_accessor(doc, blob, prim.attributes.TEXCOORD_0) * [w, h] - lm[:, :2]).max() < 0.01
    assert np.array_equal(_accessor(doc, blob, prim.indices).reshape(-1, 3), load_template().triangles)
    assert doc.meshes[0].extras["targetNames"][: len(NAMES)] == list(NAMES)
    assert doc.meshes[0].weights == [0.5, 0, 0, 0, 0]
    for k, target in enumerate(prim.targets[: len(NAMES)]):
        assert np.abs(_accessor(doc, blob, target["POSITION"]) - CM * morph_targets()[k]).max() < 1e-6
    assert doc.images[0].mimeType == "image/jpeg"


def test_video_to_animated_glb(face_video, tmp_path):
    out = tmp_path / "pan.glb"
    assert main(["face", str(face_video), "-o", str(out), "--turn"]) == 0
    _clean(validate_gltf(out))
    doc = gl.GLTF2().load(str(out))
    blob = doc.binary_blob()
    prim = doc.meshes[0].primitives[0]
    frames = len(prim.targets) - len(NAMES) + 1
    assert frames == 30
    anim = doc.animations[0]
    times = _accessor(doc, blob, anim.samplers[0].input)[:, 0]
    keys = _accessor(doc, blob, anim.samplers[0].output).reshape(frames, -1)
    assert np.allclose(np.diff(times), 1 / 30, atol=1e-6)
    # a player's vertex positions per frame: base + Σ weight · target
    base = _accessor(doc, blob, prim.attributes.POSITION)
    targets = np.stack([_accessor(doc, blob, t["POSITION"]) for t in prim.targets])
    played = base + np.einsum("ft,tvc->fvc", keys, targets)
    # the head rolls ±14° in the clip: with --turn the face turns with it, chin fixed
    chin = load_template().chin
    assert np.abs(played[:, chin] - played[0, chin]).max() < 1e-6
    spread = np.linalg.norm(played - played[0], axis=2).max(axis=1)
    assert spread.max() > 0.02                                         # metres: the face moves


def test_cli_errors_are_one_line(tmp_path, capsys, data_dir):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((200, 200, 3), 255, np.uint8))
    assert main(["face", str(blank), "-o", str(tmp_path / "x.glb")]) == 2
    assert "no face found" in capsys.readouterr().err
    assert main(["face", str(tmp_path / "nope.jpg"), "-o", str(tmp_path / "x.glb")]) == 2
    assert "nope.jpg: no such image" in capsys.readouterr().err
    photo = str(data_dir / "images" / "face" / "face_frontal_portrait.jpg")
    assert main(["face", photo, "-o", str(tmp_path / "x.obj")]) == 2
    assert ".glb" in capsys.readouterr().err
    assert main(["face", photo, "-o", str(tmp_path / "x.glb"), "--morph", "ears=1"]) == 2
    assert "ears" in capsys.readouterr().err


def test_landmark_file_for_an_image_the_tracker_misses(tmp_path, photos, capsys):
    # a face the tracker cannot see (blurred beyond recognition), annotated by hand → a face
    image, lm = photos["face_frontal_portrait.jpg"]
    h, w = image.shape[:2]
    hidden = tmp_path / "hidden.png"
    cv2.imwrite(str(hidden), cv2.blur(image, (151, 151)))
    assert main(["face", str(hidden), "-o", str(tmp_path / "x.glb")]) == 2
    assert "--landmarks" in capsys.readouterr().err
    from kinetre.face.landmarks import write_landmarks
    write_landmarks(tmp_path / "hidden.json", lm, w, h, image="hidden.png")
    assert main(["face", str(hidden), "-o", str(tmp_path / "x.glb"), "--landmarks", str(tmp_path / "hidden.json")]) == 0
    _clean(validate_gltf(tmp_path / "x.glb"))


def test_video_without_a_face_and_max_frames(tmp_path, capsys, face_video):
    import subprocess
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((120, 160, 3), 255, np.uint8))
    video = tmp_path / "blank.mp4"
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-loop", "1", "-i", str(blank), "-t", "0.3", "-r", "30",
                    "-pix_fmt", "yuv420p", str(video)], check=True, timeout=60)
    assert main(["face", str(video), "-o", str(tmp_path / "x.glb")]) == 2
    assert "no face found in any of its 9 frames" in capsys.readouterr().err
    out = tmp_path / "short.glb"
    assert main(["face", str(face_video), "-o", str(out), "--max-frames", "5"]) == 0
    assert "5 frame(s)" in capsys.readouterr().out


def test_blendshapes_must_match_the_frames(photos, tmp_path):
    from kinetre.errors import ExportError
    from kinetre.face.export import write_face_gltf
    from kinetre.skeleton.mediapipe import BLENDSHAPES
    image, lm = photos["face_frontal_portrait.jpg"]
    frames = [reconstruct(lm, image.shape[1], image.shape[0])]
    jpeg = cv2.imencode(".jpg", image)[1].tobytes()
    for bad in (np.zeros((2, 52)), np.full((1, 52), np.nan)):
        with pytest.raises(ExportError, match="x.glb: blendshapes must be 1 frames of 52 finite weights"):
            write_face_gltf(tmp_path / "x.glb", frames, jpeg, "image/jpeg", 1.0, blendshapes=bad,
                            blendshape_names=BLENDSHAPES)
    assert not (tmp_path / "x.glb").exists()
