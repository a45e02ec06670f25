"""Mesh import: every format, cleanup, and one clear error per kind of bad input."""
import gzip

import numpy as np
import pytest
import trimesh

import kinetre
from kinetre.errors import BadMeshError, KinetreError


@pytest.mark.parametrize("name, faces", [("spot.obj", 5856), ("armadillo.obj", 86482), ("camelhead.off", 22704),
                                         ("teapot.obj", None), ("sphereWithHole.stl", 285)])
def test_real_meshes_load_clean(data_dir, name, faces):
    m = kinetre.load_mesh(data_dir / "meshes" / name)
    assert m.vertices.dtype == np.float64 and m.faces.dtype == np.int32
    assert m.faces.min() >= 0 and m.faces.max() < len(m.vertices)
    assert np.allclose(np.linalg.norm(m.normals, axis=1), 1.0)
    assert m.area > 0
    if faces is not None:
        assert len(m.faces) == faces
    # every vertex referenced
    assert len(np.unique(m.faces)) == len(m.vertices)


def test_stl_soup_is_welded(data_dir):
    m = kinetre.load_mesh(data_dir / "meshes" / "sphereWithHole.stl")
    assert len(m.vertices) == 146  # 855 unindexed corners weld to 146 positions (MANIFEST)


def test_uv_seams_kept_and_share_normals(data_dir):
    m = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    assert m.uvs is not None and m.uvs.shape == (len(m.vertices), 2)
    _, inverse, counts = np.unique(m.vertices, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    assert len(counts) == 2930 and (counts > 1).any()  # seam copies exist
    dup = np.flatnonzero(counts[inverse] > 1)
    first = {}
    for v in dup:
        first.setdefault(inverse[v], v)
        assert np.allclose(m.normals[v], m.normals[first[inverse[v]]])


def test_gzipped_ply(data_dir, tmp_path):
    box = trimesh.creation.box()
    data = trimesh.exchange.ply.export_ply(box)
    p = tmp_path / "box.ply.gz"
    p.write_bytes(gzip.compress(data))
    assert len(kinetre.load_mesh(p).faces) == 12


def test_glb_scene_flattened_with_transforms(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(), transform=trimesh.transformations.translation_matrix([5, 0, 0]))
    scene.add_geometry(trimesh.creation.box(), transform=trimesh.transformations.translation_matrix([-5, 0, 0]))
    p = tmp_path / "two.glb"
    p.write_bytes(scene.export(file_type="glb"))
    m = kinetre.load_mesh(p)
    assert len(m.faces) == 24
    assert np.allclose(m.bounds, [[-5.5, -0.5, -0.5], [5.5, 0.5, 0.5]])


@pytest.mark.parametrize("ext", ["ply", "stl", "off", "obj"])
def test_formats_round_trip(tmp_path, ext):
    ico = trimesh.creation.icosphere(subdivisions=2)
    p = tmp_path / f"ico.{ext}"
    ico.export(p)
    m = kinetre.load_mesh(p)
    assert len(m.faces) == len(ico.faces)
    assert np.isclose(m.area, ico.area, rtol=1e-5)


def test_cleanup_drops_degenerate_duplicate_and_unreferenced(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [2, 2, 2], [0, 0, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 2], [0, 2, 3], [0, 0, 1], [1, 5, 1], [5, 1, 3]])
    p = tmp_path / "dirty.obj"
    p.write_text("".join(f"v {a} {b} {c}\n" for a, b, c in v) + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in f))
    m = kinetre.load_mesh(p)
    assert len(m.vertices) == 4          # the duplicate of vertex 0 is welded, vertex 4 unreferenced
    assert len(m.faces) == 3             # duplicate and two degenerate faces dropped


def _bad(tmp_path, name, content: bytes):
    p = tmp_path / name
    p.write_bytes(content)
    return p


def test_missing_file(tmp_path):
    with pytest.raises(BadMeshError, match=r"nope\.obj: file not found"):
        kinetre.load_mesh(tmp_path / "nope.obj")


def test_unreadable_garbage(tmp_path):
    p = _bad(tmp_path, "garbage.glb", b"\x00\x01 this is not a glb file at all" * 10)
    with pytest.raises(BadMeshError, match=r"garbage\.glb: cannot parse GLB"):
        kinetre.load_mesh(p)


def test_empty_file(tmp_path):
    with pytest.raises(BadMeshError, match=r"empty\.obj: file is empty"):
        kinetre.load_mesh(_bad(tmp_path, "empty.obj", b""))


def test_point_cloud(tmp_path):
    p = _bad(tmp_path, "cloud.ply", trimesh.PointCloud(np.random.default_rng(0).random((50, 3))).export(file_type="ply"))
    with pytest.raises(BadMeshError, match=r"cloud\.ply: .*(no faces|point cloud)"):
        kinetre.load_mesh(p)


def test_zero_faces_obj(tmp_path):
    with pytest.raises(BadMeshError, match=r"verts\.obj: .*(no faces|point cloud|no triangles)"):
        kinetre.load_mesh(_bad(tmp_path, "verts.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n"))


def test_nan_coordinates(tmp_path):
    p = _bad(tmp_path, "nan.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(BadMeshError, match=r"nan\.obj: 1 vertices have NaN or infinite"):
        kinetre.load_mesh(p)


def test_inf_coordinates(tmp_path):
    p = _bad(tmp_path, "inf.obj", b"v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(BadMeshError, match=r"inf\.obj: .*NaN or infinite"):
        kinetre.load_mesh(p)


def test_zero_area(tmp_path):
    p = _bad(tmp_path, "flat.obj", b"v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n")
    with pytest.raises(BadMeshError, match=r"flat\.obj: .*(degenerate|zero)"):
        kinetre.load_mesh(p)


def test_unsupported_extension(tmp_path):
    with pytest.raises(BadMeshError, match=r"model\.fbx: unsupported mesh format 'fbx'"):
        kinetre.load_mesh(_bad(tmp_path, "model.fbx", b"abc"))


def test_errors_are_kinetre_errors(tmp_path):
    with pytest.raises(KinetreError):
        kinetre.load_mesh(tmp_path)
