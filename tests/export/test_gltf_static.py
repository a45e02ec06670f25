"""The static part of a glTF take written without trimesh's exporter (a mesh without UVs or material) holds
the same indices, positions, normals and colours, with the same accessor bounds, as trimesh writes."""
from __future__ import annotations

import numpy as np
import pygltflib as gl
import pytest
from export.takes import validate_gltf
from kinetre.export.gltf import exported_document, geometry_document, write_gltf
from kinetre.mesh.mesh import Mesh

_COMPONENTS = {gl.UNSIGNED_BYTE: np.uint8, gl.UNSIGNED_SHORT: np.uint16, gl.UNSIGNED_INT: np.uint32,
               gl.FLOAT: np.float32}
_WIDTH = {gl.SCALAR: 1, gl.VEC2: 2, gl.VEC3: 3, gl.VEC4: 4}


def attribute(doc: gl.GLTF2, blob: bytes, index: int) -> tuple[np.ndarray, gl.Accessor]:
    acc = doc.accessors[index]
    view = doc.bufferViews[acc.bufferView]
    dtype = np.dtype(_COMPONENTS[acc.componentType])
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    count = acc.count * _WIDTH[acc.type]
    data = np.frombuffer(bytes(blob[start:start + count * dtype.itemsize]), dtype).reshape(acc.count, -1)
    return data, acc


def colours(kind: str, count: int):
    rng = np.random.default_rng(3)
    if kind == "none":
        return None
    return rng.integers(0, 256, (count, 4 if kind == "rgba" else 3), dtype=np.uint8)


@pytest.mark.parametrize("kind", ["none", "rgba", "rgb"])
def test_geometry_document_matches_trimesh_export(capsule_take, kind):
    mesh = capsule_take[0]
    plain = Mesh(mesh.vertices, mesh.faces, mesh.normals, colors=colours(kind, len(mesh.vertices)))
    ours, our_blob = geometry_document(plain, "take")
    theirs, their_blob = exported_document("x.glb", plain, "take")
    assert ours.scene == theirs.scene == 0
    a, b = ours.meshes[0].primitives[0], theirs.meshes[0].primitives[0]
    assert a.mode == b.mode == gl.TRIANGLES
    index_ours, acc_ours = attribute(ours, our_blob, a.indices)
    index_theirs, acc_theirs = attribute(theirs, their_blob, b.indices)
    np.testing.assert_array_equal(index_ours, index_theirs)
    assert (acc_ours.min, acc_ours.max) == (acc_theirs.min, acc_theirs.max) == ([0], [len(mesh.vertices) - 1])
    names = ["POSITION", "NORMAL"] + (["COLOR_0"] if kind != "none" else [])
    assert [n for n in ("POSITION", "NORMAL", "COLOR_0", "TEXCOORD_0") if getattr(a.attributes, n) is not None] \
        == [n for n in ("POSITION", "NORMAL", "COLOR_0", "TEXCOORD_0") if getattr(b.attributes, n) is not None] \
        == names
    for name in names:
        x, acc_x = attribute(ours, our_blob, getattr(a.attributes, name))
        y, acc_y = attribute(theirs, their_blob, getattr(b.attributes, name))
        assert (acc_x.componentType, acc_x.type, bool(acc_x.normalized)) == \
            (acc_y.componentType, acc_y.type, bool(acc_y.normalized))
        assert ours.bufferViews[acc_x.bufferView].target == theirs.bufferViews[acc_y.bufferView].target
        if name == "NORMAL":  # trimesh re-unitises the (already unit) normals in float64
            np.testing.assert_allclose(x, y, atol=1e-6)
            np.testing.assert_allclose(acc_x.min, acc_y.min, atol=1e-6)
            np.testing.assert_allclose(acc_x.max, acc_y.max, atol=1e-6)
        else:
            np.testing.assert_array_equal(x, y)
            assert (acc_x.min, acc_x.max) == (acc_y.min, acc_y.max)
    if kind == "rgb":
        x, _ = attribute(ours, our_blob, a.attributes.COLOR_0)
        np.testing.assert_array_equal(x[:, :3], plain.colors)
        assert (x[:, 3] == 255).all()


def test_plain_mesh_take_is_valid(tmp_path, capsule_take):
    mesh, graph, poses, fps = capsule_take
    out = tmp_path / "plain.glb"
    write_gltf(out, Mesh(mesh.vertices, mesh.faces, mesh.normals), graph, poses[:4], fps)
    report = validate_gltf(out)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    doc = gl.GLTF2().load(str(out))
    assert doc.materials == [] and doc.meshes[0].primitives[0].attributes.TEXCOORD_0 is None
    assert doc.scene == 0 and doc.scenes[0].nodes == [0, 1]  # players show the default scene


def test_skin_weights_same_for_float32_and_float64_tables(capsule_take):
    import dataclasses
    from kinetre.export.gltf import skin_weights
    graph = capsule_take[1]
    rng = np.random.default_rng(5)
    raw = rng.random(graph.vertex_weights.shape) ** 3  # unnormalised, some rows far from summing to 1
    narrow = dataclasses.replace(graph, vertex_weights=raw.astype(np.float32),
                                 vertex_nodes=graph.vertex_nodes.astype(np.int32))
    wide = dataclasses.replace(graph, vertex_weights=raw.astype(np.float32).astype(np.float64),
                               vertex_nodes=graph.vertex_nodes.astype(np.int64))
    (j32, w32), (j64, w64) = skin_weights(narrow), skin_weights(wide)
    np.testing.assert_array_equal(j32, j64)
    assert w32.tobytes() == w64.tobytes()
    assert np.abs(w32.astype(np.float64).sum(axis=1) - 1).max() < 1e-6
