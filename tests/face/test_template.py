"""The shipped template is MediaPipe's canonical face mesh, as read from the npm package's assets."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from kinetre.face.assets import extract, fields
from kinetre.face.template import load_template

PACKAGE = Path(__file__).resolve().parents[2] / "web" / "node_modules" / "@mediapipe" / "face_mesh"


def test_template_shape_and_topology():
    t = load_template()
    assert t.vertices.shape == (468, 3) and t.uvs.shape == (468, 2) and t.triangles.shape == (898, 3)
    assert np.array_equal(np.unique(t.triangles), np.arange(468))           # every vertex used
    edges = np.sort(np.concatenate([t.triangles[:, [0, 1]], t.triangles[:, [1, 2]], t.triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert counts.max() == 2                                                 # a manifold surface (open at the rim)
    assert t.chin == int(np.argmin(t.vertices[:, 1]))                        # the chin is the lowest vertex
    assert abs(t.vertices[t.chin, 0]) < 1e-6
    assert np.array_equal(t.mirror[t.mirror], np.arange(468))                # left/right swap is an involution
    assert np.allclose(t.vertices[t.mirror] * [-1, 1, 1], t.vertices, atol=1e-3)
    assert (t.weights > 0).sum() >= 20 and (t.weights[[13, 14, 17, 0]] == 0).all()   # lips are not rigid


def test_wire_reader_on_a_hand_made_message():
    # field 1 varint 150, field 2 fixed32 1.5, field 3 bytes "hi"
    msg = bytes([0x08, 0x96, 0x01, 0x15]) + np.float32(1.5).tobytes() + bytes([0x1A, 2]) + b"hi"
    got = list(fields(msg))
    assert got[0] == (1, 0, 150) and got[2] == (3, 2, b"hi")
    assert np.frombuffer(got[1][2], "<f4")[0] == 1.5


@pytest.mark.skipif(not PACKAGE.is_dir(), reason="web/node_modules not installed (make setup installs it)")
def test_shipped_template_matches_the_npm_asset():
    shipped = json.loads((Path(__file__).resolve().parents[2] / "src" / "kinetre" / "data" /
                          "face_template.json").read_text())
    fresh = extract(PACKAGE)
    assert fresh["triangles"] == shipped["triangles"] and fresh["mirror"] == shipped["mirror"]
    for key in ("vertices", "uvs", "procrustes_weights"):
        assert np.allclose(fresh[key], shipped[key], atol=1e-6), key
