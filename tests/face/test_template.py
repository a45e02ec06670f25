"""The shipped template is MediaPipe's canonical face mesh, as read from the face_landmarker.task bundle."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from kinetre.face.assets import BadAssetError, extract, fields, main
from kinetre.face.template import load_template
from kinetre.motion.models import model_path


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


def test_shipped_template_is_the_canonical_mesh_of_the_face_model(tmp_path, capsys):
    shipped = json.loads((Path(__file__).resolve().parents[2] / "src" / "kinetre" / "data" /
                          "face_template.json").read_text())
    out = tmp_path / "template.json"
    assert main(["-o", str(out)]) == 0
    fresh = json.loads(out.read_text())
    assert fresh["source"].startswith("face_landmarker.task (sha256 64184e22")
    for key in ("triangles", "mirror", "chin", "nose_tip", "vertices", "uvs", "procrustes_weights"):
        assert fresh[key] == shipped[key], key
    assert extract(model_path("face_landmarker.task"))["vertices"] == shipped["vertices"]


def test_bad_model_bundles_name_the_file(tmp_path, capsys):
    import zipfile
    with pytest.raises(BadAssetError, match="missing.task: no such model file"):
        extract(tmp_path / "missing.task")
    junk = tmp_path / "junk.task"
    junk.write_bytes(b"not a zip")
    with pytest.raises(BadAssetError, match="junk.task: not a .task model bundle"):
        extract(junk)
    empty = tmp_path / "empty.task"
    with zipfile.ZipFile(empty, "w") as z:
        z.writestr("face_detector.tflite", b"")
    with pytest.raises(BadAssetError, match="empty.task: the model bundle holds no geometry_pipeline"):
        extract(empty)
    assert main(["--task", str(junk), "-o", str(tmp_path / "t.json")]) == 2
    err = capsys.readouterr().err
    assert "junk.task" in err and err.count("\n") == 1 and not (tmp_path / "t.json").exists()
