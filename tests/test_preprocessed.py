"""A mesh file's preprocessing kept between runs (kinetre.preprocessed): found again by the file's content and
the settings, missed when either changes, and the output of `kinetre animate` the same with it or without."""
from __future__ import annotations

import dataclasses
import os
import shutil

import numpy as np
import pytest

import kinetre
from kinetre.cli import main
from kinetre.preprocessed import MeshCache, prune


@pytest.fixture()
def teapot(data_dir, tmp_path):
    path = tmp_path / "teapot.obj"
    shutil.copyfile(data_dir / "meshes" / "teapot.obj", path)
    return path


def _same_mesh(a, b):
    for name in ("vertices", "faces", "normals", "uvs", "colors"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert x.dtype == y.dtype and np.array_equal(x, y), name


def test_a_kept_mesh_is_the_loaded_mesh_and_a_changed_file_misses(teapot, tmp_path):
    folder = tmp_path / "cache"
    first = MeshCache.of_file(teapot, folder).load_mesh()  # loaded, then kept
    assert len(list(folder.glob("*.mesh.npz"))) == 1
    again = MeshCache.of_file(teapot, folder).load_mesh()
    _same_mesh(again, kinetre.load_mesh(teapot))
    _same_mesh(again, first)
    assert again.source == str(teapot)
    # the same name with other content: a miss, and the new mesh (not the kept one)
    text = teapot.read_text().splitlines()
    first_vertex = next(i for i, line in enumerate(text) if line.startswith("v "))
    x, y, z = map(float, text[first_vertex].split()[1:4])
    text[first_vertex] = f"v {x + 0.05} {y} {z}"
    teapot.write_text("\n".join(text) + "\n")
    changed = MeshCache.of_file(teapot, folder).load_mesh()
    assert len(list(folder.glob("*.mesh.npz"))) == 2
    assert not np.array_equal(changed.vertices, first.vertices)
    _same_mesh(changed, kinetre.load_mesh(teapot))


def test_a_kept_graph_is_found_only_for_its_settings(teapot, tmp_path):
    folder = tmp_path / "cache"
    kept = MeshCache.of_file(teapot, folder)
    mesh = kept.load_mesh()
    graph = kinetre.build_graph(mesh, nodes=64, seed=0)
    kept.keep_graph(graph, "y", 64, 0)
    back = MeshCache.of_file(teapot, folder).graph("y", 64, 0)
    for name in ("nodes", "normals", "edges", "bridges", "vertex_nodes", "vertex_weights", "pieces"):
        want, got = getattr(graph, name), getattr(back, name)
        assert got.dtype == want.dtype and np.array_equal(got, want), name
    assert back.radius == graph.radius
    for up, nodes, seed in (("z", 64, 0), ("y", 65, 0), ("y", 64, 1)):  # any other setting: a miss
        assert kept.graph(up, nodes, seed) is None
    # another file's cache (other content) does not see it
    other = tmp_path / "other.obj"
    other.write_text(teapot.read_text() + "# another file\n")
    assert MeshCache.of_file(other, folder).graph("y", 64, 0) is None


def test_a_kept_up_axis_is_found_for_its_file_kind_only(teapot, tmp_path):
    from kinetre.mesh.upright import find_upright
    kept = MeshCache.of_file(teapot, tmp_path)
    mesh = kept.load_mesh()
    found = find_upright(mesh, mesh.source)
    assert kept.upright(str(teapot)) is None
    topples = dataclasses.replace(found, scores={**found.scores, "-y": -np.inf})  # -inf: a side it topples on
    kept.keep_upright(str(teapot), topples)
    assert MeshCache.of_file(teapot, tmp_path).upright(str(teapot)) == topples
    assert kept.upright(str(teapot.with_suffix(".glb"))) is None  # glTF is +Y up by its specification


def test_a_damaged_entry_is_a_miss_and_is_written_again(teapot, tmp_path):
    folder = tmp_path / "cache"
    MeshCache.of_file(teapot, folder).load_mesh()
    entry = next(folder.glob("*.mesh.npz"))
    data = bytearray(entry.read_bytes())
    data[len(data) // 2] ^= 0xFF  # a flipped byte inside an array: its checksum no longer matches
    entry.write_bytes(bytes(data))
    _same_mesh(MeshCache.of_file(teapot, folder).load_mesh(), kinetre.load_mesh(teapot))
    entry.write_bytes(b"")  # an emptied file
    _same_mesh(MeshCache.of_file(teapot, folder).load_mesh(), kinetre.load_mesh(teapot))
    assert np.load(entry)["vertices"].shape[1] == 3  # written whole again


def test_an_unwritable_folder_only_skips_keeping(teapot, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    _same_mesh(MeshCache.of_file(teapot, blocker / "cache").load_mesh(), kinetre.load_mesh(teapot))
    assert MeshCache.of_file(tmp_path / "missing.obj", tmp_path) is None  # the loader says what is wrong


def test_a_mesh_with_a_material_is_loaded_but_not_kept(data_dir, tmp_path):
    spot = data_dir / "meshes" / "spot.obj"  # a texture image: no arrays-only entry can hold it
    mesh = MeshCache.of_file(spot, tmp_path).load_mesh()
    assert mesh.material is not None and mesh.uvs is not None
    assert list(tmp_path.iterdir()) == []


def test_prune_drops_the_least_recently_used(tmp_path):
    for i, name in enumerate(("a", "b", "c")):
        path = tmp_path / f"{name}.mesh.npz"
        path.write_bytes(b"\0" * 1000)
        os.utime(path, (1000 + i, 1000 + i))
    prune(tmp_path, 2500)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.mesh.npz", "c.mesh.npz"]


def test_animate_writes_the_same_file_from_kept_preprocessing(teapot, tmp_path, monkeypatch, capsys, data_dir):
    import kinetre.preprocessed
    monkeypatch.setattr(kinetre.preprocessed, "user_cache_dir", lambda: tmp_path / "user-cache")
    walk = data_dir / "bvh" / "cmu_12_01_walk.bvh"
    argv = ["animate", str(teapot), "--motion", str(walk), "--max-frames", "6", "--nodes", "64", "-q"]
    outputs = []
    for name, extra in (("fresh", ["--no-cache"]), ("kept-first", []), ("kept-again", [])):
        out = tmp_path / f"{name}.glb"
        assert main([*argv, "-o", str(out), *extra]) == 0
        outputs.append(out.read_bytes())
    capsys.readouterr()
    entries = sorted(p.name.split(".", 1)[1] for p in (tmp_path / "user-cache" / "meshes").iterdir())
    assert entries == ["graph.npz", "mesh.npz", "upright.npz"]
    assert outputs[0] == outputs[1] == outputs[2]
