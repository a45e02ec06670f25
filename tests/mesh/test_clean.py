"""`clean` skips trimesh's cleanup only when it would change nothing, and gives trimesh's result either way."""
import gzip
import io

import numpy as np
import pytest
import trimesh

from kinetre.mesh.clean import _rounded_rows_distinct, _sorted_rows_distinct, clean, is_clean


def trimesh_cleanup(tm):
    tm = tm.copy()
    tm.merge_vertices()
    tm.update_faces(tm.nondegenerate_faces(height=None))
    tm.update_faces(tm.unique_faces())
    tm.remove_unreferenced_vertices()
    return tm


def load(path):
    data = gzip.decompress(path.read_bytes()) if path.suffix == ".gz" else path.read_bytes()
    kind = path.name.removesuffix(".gz").rsplit(".", 1)[-1]
    return trimesh.load(io.BytesIO(data), file_type=kind, process=False, force="mesh")


@pytest.mark.parametrize("name", ["spot.obj", "armadillo.obj", "camelhead.off", "teapot.obj", "sphereWithHole.stl",
                                  "elephant_loop3_large.ply.gz"])
def test_same_as_trimesh_cleanup_on_real_meshes(data_dir, name):
    tm = load(data_dir / "meshes" / name)
    ours, theirs = clean(tm), trimesh_cleanup(tm)
    assert np.array_equal(ours.vertices, theirs.vertices) and np.array_equal(ours.faces, theirs.faces)
    # the fast path is taken exactly when trimesh changes nothing
    unchanged = len(theirs.vertices) == len(tm.vertices) and np.array_equal(theirs.faces, tm.faces)
    assert is_clean(tm) == unchanged
    if name in ("armadillo.obj", "elephant_loop3_large.ply.gz"):
        assert is_clean(tm)  # the big clean meshes take the fast path
    if name in ("sphereWithHole.stl", "teapot.obj"):
        assert not is_clean(tm)  # unwelded copies


def grid():
    v, f = trimesh.creation.box().vertices, trimesh.creation.box().faces
    v, f = trimesh.remesh.subdivide(v, f)
    return trimesh.Trimesh(v, f, process=False)


@pytest.mark.parametrize("defect", ["duplicate_vertex", "near_duplicate_vertex", "degenerate_face", "collinear_face",
                                    "duplicate_face", "unused_vertex"])
def test_each_defect_goes_to_trimesh(defect):
    tm = grid()
    assert is_clean(tm)
    v, f = tm.vertices.copy(), tm.faces.copy()
    if defect == "duplicate_vertex":  # a copy of vertex 0 used by face 0
        v = np.vstack([v, v[:1]])
        f[0, 0 if f[0, 0] == 0 else 1] = len(v) - 1
    elif defect == "near_duplicate_vertex":  # equal after trimesh's rounding to 1e-8
        v = np.vstack([v, v[:1] + 1e-12])
        f[0, list(f[0]).index(0) if 0 in f[0] else 0] = len(v) - 1
    elif defect == "degenerate_face":
        f = np.vstack([f, [[f[0, 0], f[0, 0], f[0, 1]]]])
    elif defect == "collinear_face":  # three distinct vertices on a line
        v = np.vstack([v, [[10.0, 0, 0], [11.0, 0, 0], [12.0, 0, 0]]])
        f = np.vstack([f, [[len(v) - 3, len(v) - 2, len(v) - 1]]])
    elif defect == "duplicate_face":  # the same corners in another order
        f = np.vstack([f, f[3, [1, 2, 0]]])
    else:
        v = np.vstack([v, [[5.0, 5.0, 5.0]]])
    tm = trimesh.Trimesh(v, f, process=False)
    assert not is_clean(tm)
    ours, theirs = clean(tm), trimesh_cleanup(tm)
    assert np.array_equal(ours.vertices, theirs.vertices) and np.array_equal(ours.faces, theirs.faces)


def test_rounded_key_check_rounds_as_numpy():
    # 1.5 and 2.5 both round to 2 (half to even), 0.5 to 0: numpy's .round(), which trimesh's weld uses
    scales = np.array([1.0, 10.0])
    for rows in ([[1.5, 0.0], [2.5, 0.0]], [[0.5, 0.1], [0.0, 0.1]], [[0.5, 0.1], [1.0, 0.1]], [[3.0, 0.26], [3.0, 0.34]]):
        values = np.array(rows)
        unique = len(np.unique((values * scales).round().astype(np.int64), axis=0)) == len(values)
        assert _rounded_rows_distinct(values, scales) == unique


@pytest.mark.parametrize("fan", [3, 40])
def test_duplicate_face_check_equals_numpy_unique(fan):
    # sorted corner triples; vertex 0 starts `fan` faces (the sort path above 16, pairwise below)
    rng = np.random.default_rng(fan)
    rows = np.sort(rng.integers(0, 60, (3000, 3)), axis=1)
    rows = rows[(rows[:, 0] < rows[:, 1]) & (rows[:, 1] < rows[:, 2])]
    rows = np.unique(rows, axis=0)
    rows = np.vstack([rows[rows[:, 0] != 0], [[0, 1 + k, 2 + k] for k in range(fan)]])
    rows = np.ascontiguousarray(rng.permutation(rows), dtype=np.int64)
    assert _sorted_rows_distinct(rows, 60 + fan)
    for a, b in ((0, len(rows) - 1), (len(rows) // 2, 7)):
        dup = np.vstack([rows, rows[[a]]]) if b == len(rows) - 1 else rows.copy()
        if b != len(rows) - 1:
            dup[b] = dup[a]
        assert len(np.unique(dup, axis=0)) < len(dup)
        assert not _sorted_rows_distinct(np.ascontiguousarray(dup), 60 + fan)
    fan_dup = np.vstack([rows, [[0, 1 + fan // 2, 2 + fan // 2]]])  # a repeat inside vertex 0's fan
    assert not _sorted_rows_distinct(np.ascontiguousarray(fan_dup), 60 + fan)


@pytest.mark.parametrize("name", ["spot.obj", "camelhead.off", "teapot.obj"])
def test_normals_and_area_equal_the_numpy_sums(data_dir, name):
    from kinetre.mesh.normals import normals_and_area

    tm = clean(load(data_dir / "meshes" / name))
    v, f = np.asarray(tm.vertices, dtype=np.float64), np.asarray(tm.faces)
    for weld in (False, True):
        _, index = np.unique(v, axis=0, return_inverse=True) if weld else (None, np.arange(len(v)))
        index = index.reshape(-1)
        tri = v[f]
        face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        corners = index[f].reshape(-1)
        acc = np.stack([np.bincount(corners, np.repeat(face_n[:, c], 3), minlength=index.max() + 1)
                        for c in range(3)], axis=1)[index]
        expected = acc / np.linalg.norm(acc, axis=1)[:, None]
        normals, area = normals_and_area(v, f, weld=weld)
        assert np.array_equal(normals, expected)  # same sums in the same order: bit for bit
        assert area == pytest.approx(0.5 * np.linalg.norm(face_n, axis=1).sum(), rel=1e-12)
