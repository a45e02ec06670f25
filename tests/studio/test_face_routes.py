"""The studio's face routes: the template the page uses, and face takes exported as GLB (or refused)."""
from __future__ import annotations

import base64

import cv2
import numpy as np
import pygltflib
from starlette.applications import Starlette
from starlette.testclient import TestClient

from kinetre.face.caricature import NAMES
from kinetre.face.reconstruct import reconstruct
from kinetre.face.template import load_template
from kinetre.studio.face_routes import face_routes


def _client():
    return TestClient(Starlette(routes=face_routes()))


def _synthetic_take(frames=4):
    """Landmarks of the template seen frontally, nodding a little: pixels (x, y down, z), 640x480."""
    t = load_template()
    out = []
    for k in range(frames):
        a = np.radians(5 * k)
        r = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        p = 12 * t.vertices @ r.T
        out.append(np.c_[320 + p[:, 0], 240 - p[:, 1], -p[:, 2]])
    return out


def test_template_payload_matches_the_package():
    body = _client().get("/api/face/template").json()
    t = load_template()
    assert len(body["vertices"]) == 3 * 468 and len(body["triangles"]) == 3 * 898
    assert np.allclose(body["vertices"], t.vertices.ravel(), atol=1e-5)
    assert body["chin"] == t.chin and body["morphNames"] == list(NAMES)
    assert len(body["morphs"]) == len(NAMES) and set(body["presets"]) >= {"none", "big eyes"}


def test_face_take_exports_an_animated_glb(tmp_path):
    frames = _synthetic_take()
    ok, jpg = cv2.imencode(".jpg", np.full((480, 640, 3), 128, np.uint8))
    body = {"width": 640, "height": 480, "fps": 20, "image": base64.b64encode(jpg.tobytes()).decode(),
            "frames": [f.ravel().tolist() for f in frames[:2]] + [None] + [frames[3].ravel().tolist()],
            "weights": [0.5, 0, 0, 0, 0.25]}
    r = _client().post("/api/face/export", json=body)
    assert r.status_code == 200 and r.headers["content-type"] == "model/gltf-binary"
    path = tmp_path / "take.glb"
    path.write_bytes(r.content)
    glb = pygltflib.GLTF2().load(str(path))
    assert glb.meshes[0].weights[: len(NAMES)] == [0.5, 0, 0, 0, 0.25]
    assert len(glb.meshes[0].primitives[0].targets) == len(NAMES) + 3       # the lost frame holds the last face
    first = reconstruct(frames[0], 640, 480)
    acc = glb.accessors[glb.meshes[0].primitives[0].attributes.POSITION]
    view = glb.bufferViews[acc.bufferView]
    base = np.frombuffer(glb.binary_blob(), "<f4", 468 * 3, view.byteOffset or 0).reshape(468, 3)
    assert np.abs(base - first.vertices).max() < 1e-6


def test_bad_face_takes_are_refused_with_a_message():
    c = _client()
    r = c.post("/api/face/export", json={"width": 640})
    assert r.status_code == 400 and "malformed" in r.json()["error"]
    jpg = base64.b64encode(cv2.imencode(".jpg", np.zeros((8, 8, 3), np.uint8))[1].tobytes()).decode()
    take = {"width": 640, "height": 480, "image": jpg}
    r = c.post("/api/face/export", json={**take, "frames": [None, None]})
    assert r.status_code == 400 and "no frame holds a face" in r.json()["error"]
    r = c.post("/api/face/export", json={**take, "frames": [[1, 2, 3]]})
    assert r.status_code == 400 and "frame 0 must hold 468" in r.json()["error"]
    r = c.post("/api/face/export", json={**take, "image": "aGVsbG8=", "frames": [_synthetic_take(1)[0].ravel().tolist()]})
    assert r.status_code == 400 and "JPEG" in r.json()["error"]
    r = c.post("/api/face/export", content=b"{not json", headers={"content-type": "application/json"})
    assert r.status_code == 400 and "not JSON" in r.json()["error"]
