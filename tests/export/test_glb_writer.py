"""Our GLB/glTF writer gives the document pygltflib would write, and the polar bound equals its direct form."""
from __future__ import annotations

import base64
import json

import numpy as np
import pygltflib as gl
import pytest

import kinetre
from kinetre.export import gltf


def pygltflib_save(path, doc, blob, generator):
    # what save_gltf did before: pygltflib's own writers
    doc.buffers = [gl.Buffer(byteLength=len(blob))]
    doc.asset = gl.Asset(version="2.0", generator=generator)
    if path.suffix == ".glb":
        doc.set_binary_blob(bytes(blob))
        doc.save_binary(str(path))
    else:
        doc.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
        doc.save_json(str(path))


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_writer_matches_pygltflib(tmp_path, data_dir, monkeypatch, suffix):
    mesh = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")  # UVs, material and texture image
    graph = kinetre.build_graph(mesh, nodes=40)
    rng = np.random.default_rng(0)
    n = graph.node_count
    poses = [kinetre.GraphPose(np.eye(3) + 0.1 * rng.standard_normal((n, 3, 3)), 0.01 * rng.standard_normal((n, 3)))
             for _ in range(4)]
    gltf.write_gltf(tmp_path / f"ours{suffix}", mesh, graph, poses, 30.0)
    monkeypatch.setattr(gltf, "save_gltf", pygltflib_save)
    gltf.write_gltf(tmp_path / f"theirs{suffix}", mesh, graph, poses, 30.0)
    ours, theirs = gl.GLTF2.load(tmp_path / f"ours{suffix}"), gl.GLTF2.load(tmp_path / f"theirs{suffix}")
    assert json.loads(ours.to_json()) == json.loads(theirs.to_json())
    if suffix == ".glb":
        assert ours.binary_blob() == theirs.binary_blob()
        assert (tmp_path / "ours.glb").read_bytes() == (tmp_path / "theirs.glb").read_bytes()


def test_polar_error_bound_equals_the_direct_norm(data_dir):
    mesh = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    graph = kinetre.build_graph(mesh, nodes=50)
    n = graph.node_count
    rng = np.random.default_rng(1)
    r = np.eye(3) + 0.4 * rng.standard_normal((6, n, 3, 3))
    r[0, :5] *= -1.0            # reflections: det < 0
    r[1, :5, 2] = r[1, :5, 0]   # singular
    direct = np.linalg.norm(r - gltf.polar_rotations(r), ord=2, axis=(2, 3))
    dist = np.linalg.norm(mesh.vertices[:, None] - graph.nodes[graph.vertex_nodes], axis=2)
    dist[graph.vertex_weights <= 0] = 0.0
    reach = np.zeros(n)
    np.maximum.at(reach, graph.vertex_nodes.ravel(), dist.ravel())
    assert gltf.polar_error_bound(mesh, graph, r) == pytest.approx((direct * reach).max(), rel=1e-12)
    for f in range(6):  # per frame too: the worst frame is not always the same one
        assert gltf.polar_error_bound(mesh, graph, r[f:f + 1]) == pytest.approx((direct[f] * reach).max(), rel=1e-12)
