"""The studio's face features in a real browser (tests/e2e/driver_face.mjs): the live face puppet from a fake
camera playing a face video, caricature presets, a recorded face take exported as GLB, and the /annotate page.

The fake camera plays the shared portrait panned and rolled (made with ffmpeg). Screenshots land in
tests/e2e/artifacts/ (gitignored); face-live.png shows the textured puppet beside the mesh.
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pygltflib
import pytest
from export.takes import validate_gltf
from face.fixtures_face import pan_video
from e2e.node_driver import run_driver
from studio.conftest import start_server

from kinetre.cli import main
from kinetre.face.caricature import NAMES, morph_targets
from kinetre.face.landmarks import FaceTracker, mirrored, read_landmarks
from kinetre.face.reconstruct import CM, reconstruct
from kinetre.face.template import load_template

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
ARTIFACTS = HERE / "artifacts"
FACES = ROOT / ".." / "shared" / "data" / "images" / "face"
PORTRAIT = FACES / "face_frontal_portrait.jpg"


def drive(url: str, scenario: str, video: Path, timeout: float = 900, **extra) -> dict:
    assert (ROOT / "src" / "kinetre" / "studio" / "static" / "annotate" / "index.html").is_file(), "run `make web`"
    config = {"scenario": scenario, "url": url, "video": str(video), "artifacts": str(ARTIFACTS), **extra}
    result = run_driver("driver_face.mjs", config, timeout)
    errors = [s for s in result["steps"] if "error" in s["step"]]
    assert not errors, errors
    return result


@pytest.fixture(scope="module")
def page_url():
    proc, url = start_server(nodes=64, sample_motion=False)
    yield url
    proc.terminate()
    proc.wait(60)


@pytest.fixture(scope="module")
def face_y4m(tmp_path_factory):
    path = tmp_path_factory.mktemp("face-camera") / "pan.y4m"
    pan_video(PORTRAIT.resolve(), path, seconds=3.0)
    return path


@pytest.fixture(scope="module")
def tracked():
    """MediaPipe (Python) landmarks of the two photos: [(landmarks (468, 3), width, height)]."""
    out = []
    with FaceTracker(static_image=True) as tracker:
        for path in sorted(FACES.glob("*.[jp][pn]g")):
            image = cv2.imread(str(path))
            out.append((tracker.track(image), image.shape[1], image.shape[0]))
    return out


def test_live_face_puppet_moves_takes_caricatures_and_exports(page_url, face_y4m, tracked):
    cases = [{"landmarks": lm.ravel().tolist(), "width": w, "height": h} for lm, w, h in tracked]
    avatar = (ROOT / ".." / "shared" / "data" / "avatars" / "CesiumMan.glb").resolve()
    r = drive(page_url, "face", face_y4m, cases=cases, avatar=str(avatar))
    # the page's Algorithm 2 gives the Python module's face (float32 vs float64)
    chin = load_template().chin
    for (lm, w, h), got in zip(tracked, r["reconstructed"]):
        frame = reconstruct(lm, w, h)
        expected = CM * (frame.face - frame.face[chin])
        assert np.abs(np.reshape(got["face"], (-1, 3)) - expected).max() < 1e-5                  # metres
        assert np.abs(np.reshape(got["uvs"], (-1, 2)) - np.c_[frame.uvs[:, 0], 1 - frame.uvs[:, 1]]).max() < 1e-6
        assert np.abs(np.reshape(got["rotation"], (3, 3)) - frame.pose.rotation).max() < 1e-4
    # the live face: tracked, textured from the camera, and moving with the panned, rolled head
    samples = r["samples"]
    assert samples[-1]["tracked"] > samples[0]["tracked"] >= 3
    v = np.array([s["vertices"] for s in samples])                     # (samples, 8, 3) world metres
    uv = np.array([s["uvs"] for s in samples])
    assert np.isfinite(v).all()
    assert np.linalg.norm(v - v[0], axis=2).max() > 0.02               # the puppet moves (metres)
    assert np.abs(uv - uv[0]).max() > 0.02                             # the live texture coordinates follow
    assert r["rate"]["landmarksPerSecond"] > 0
    (ARTIFACTS / "face-rate.json").write_text(json.dumps({"landmarks_per_second": r["rate"]["landmarksPerSecond"],
                                                          "detect_ms": r["rate"]["detectMs"]}))
    # the "big eyes" preset: outer eye corners (33, 263) move apart relative to forehead-chin (10, 152)
    before, after = np.array(r["morphEffect"]["plain"]), np.array(r["morphEffect"]["morphed"])
    ratio = lambda p: np.linalg.norm(p[3] - p[6]) / np.linalg.norm(p[2] - p[5])   # sample: 0 1 10 33 61 152 263 291
    assert r["caricature"]["weights"] == [1, 0, 0, 0, 0]
    assert ratio(after) > 1.05 * ratio(before)
    # the face take: a validator-clean GLB with the caricature morphs at the chosen weights
    assert r["take"] and r["take"]["frames"] >= 3, r["message"]
    report = validate_gltf(r["glb"])
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]["messages"][:5]
    glb = pygltflib.GLTF2().load(r["glb"])
    assert glb.meshes[0].extras["targetNames"][: len(NAMES)] == list(NAMES)
    assert glb.meshes[0].weights[:len(NAMES)] == [1.0, 0, 0, 0, 0]
    assert glb.animations and len(glb.meshes[0].primitives[0].targets) == len(NAMES) + r["take"]["frames"] - 1
    # three.js (GLTFLoader + AnimationMixer) plays it as the glTF reading says: base + Σ weight · target
    played = r["played"]
    assert played["targets"] == len(NAMES) + r["take"]["frames"] - 1
    expected = _player_positions(glb, played["times"], [0, 1, 10, 33, 61, 152, 263, 291])
    assert np.abs(np.array(played["positions"]) - expected).max() < 1e-5

    # on an avatar: the chin on its neck, the face upright above it (sample index 2 is vertex 10, the forehead)
    on = r["onAvatar"]
    neck, head, chin = (np.array(on[k]) for k in ("neck", "head", "chin"))
    assert on["anchor"] == "avatar"
    assert np.linalg.norm(chin - neck) < 0.12 and chin[2] - neck[2] > 0.05        # in front: it faces the camera
    up = (head - neck) / np.linalg.norm(head - neck)
    assert (np.array(on["vertices"][2]) - chin) @ up > 0.1                           # life size, upright


def _player_positions(glb, times, indices) -> np.ndarray:
    """Vertex positions (len(times), len(indices), 3) of a morph-animated glTF mesh at `times` (keys)."""
    blob = glb.binary_blob()

    def read(index, width):
        acc = glb.accessors[index]
        view = glb.bufferViews[acc.bufferView]
        return np.frombuffer(blob, "<f4", acc.count * width, (view.byteOffset or 0) + (acc.byteOffset or 0)).reshape(acc.count, width)
    prim = glb.meshes[0].primitives[0]
    base = read(prim.attributes.POSITION, 3)
    targets = np.stack([read(t["POSITION"], 3) for t in prim.targets])
    sampler = glb.animations[0].samplers[0]
    keys_t = read(sampler.input, 1)[:, 0]
    weights = read(sampler.output, 1).reshape(len(keys_t), -1)
    out = []
    for t in times:
        w = np.array([np.interp(t, keys_t, weights[:, k]) for k in range(weights.shape[1])])
        out.append((base + np.tensordot(w, targets, axes=1))[indices])
    return np.array(out)


def _projected(pose: dict) -> np.ndarray:
    t = load_template()
    a, b, c = np.radians([pose["yaw"], pose["pitch"], pose["roll"]])
    ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    v = t.vertices + np.tensordot(np.asarray(pose["weights"]), morph_targets(), axes=1)
    p = pose["scale"] * v @ (rz @ rx @ ry).T
    return np.c_[pose["x"] + p[:, 0], pose["y"] - p[:, 1]]


def test_annotation_page_saves_mirrors_and_reloads(page_url, face_y4m, tracked, tmp_path, capsys):
    pose = {"scale": 14.0, "yaw": 20.0, "pitch": -10.0, "roll": 5.0, "x": 410.0, "y": 330.0,
            "weights": [0.2, 0.0, -0.3, 0.5, 0.0]}
    r = drive(page_url, "annotate", face_y4m, image=str(PORTRAIT.resolve()), pose=pose)
    lm, w, h = next((lm, w, h) for lm, w, h in tracked if (w, h) == (820, 1024))
    # "fit with the tracker": the rigid template on the tracked face, close to MediaPipe's own landmarks
    fitted = np.array(r["fitted"]["landmarks"])
    err = np.linalg.norm(fitted - lm[:, :2], axis=1)
    assert np.median(err) < 8.0, np.median(err)
    # the annotator's drag (20 px) and jaw slider reach the file
    adjusted = r["adjusted"]["annotation"]
    assert adjusted["x"] - r["fitted"]["annotation"]["x"] == pytest.approx(20, abs=2)
    assert adjusted["weights"][NAMES.index("jaw")] == 0.5
    # a chosen pose projects exactly as the template does in Python, and the mirror uses the permutation
    path = tmp_path / "portrait.landmarks.json"
    path.write_text(json.dumps(r["posed"]))
    points, fw, fh = read_landmarks(path)
    assert (fw, fh) == (820, 1024)
    assert np.abs(points - _projected(pose)).max() < 0.01
    assert np.abs(read_landmarks(path, flipped=True)[0] - mirrored(points, fw)).max() < 0.01
    # reloading the file restores the pose it was saved with
    assert {k: r["reloaded"][k] for k in pose} == pose
    assert "not a kinetre landmark file" in r["badMessage"]
    # and the file drives `kinetre face` for that image
    out = tmp_path / "annotated.glb"
    assert main(["face", str(PORTRAIT), "--landmarks", str(path), "-o", str(out)]) == 0
    assert validate_gltf(out)["issues"]["numErrors"] == 0
