"""glTF export: valid per the Khronos validator, and skinned by an independent player it matches
Kinetre's own deformation within 1 % of the bounding-box diagonal at every frame."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
import trimesh
from export.takes import bend_poses, reference_skin, synthetic_graph, validate_gltf
from export.gltf_player import GltfPlayer
from kinetre.deform.pose import GraphPose
from kinetre.errors import ExportError
from kinetre.export.gltf import (polar_error_bound, polar_rotations, skin_weights, stretch_factors,
                                 write_gltf)
from kinetre.rotation import matrix_quaternions
from kinetre.mesh.mesh import Mesh
from PIL import Image


def fidelity(path, mesh, graph, poses, fps, skin=reference_skin):
    """Per-frame max vertex error of the player's skinning vs ours, as a fraction of the bbox diagonal."""
    player = GltfPlayer(path)
    np.testing.assert_allclose(player.positions, mesh.vertices, atol=1e-6 * mesh.diagonal)
    errors = []
    for k, pose in enumerate(poses):
        theirs = player.skin(k / fps)
        ours = skin(mesh, graph, pose)
        errors.append(np.linalg.norm(theirs - ours, axis=1).max() / mesh.diagonal)
    return np.array(errors)


@pytest.mark.parametrize("suffix,stretch", [(".glb", False), (".gltf", False), (".glb", True)])
def test_capsule_take_is_valid_and_faithful(tmp_path, capsule_take, suffix, stretch):
    mesh, graph, poses, fps = capsule_take
    out = tmp_path / f"capsule{suffix}"
    write_gltf(out, mesh, graph, poses, fps, name="bend", stretch=stretch)

    report = validate_gltf(out)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
    assert report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    assert report["info"]["hasSkins"] and report["info"]["animationCount"] == 1
    assert report["info"]["totalVertexCount"] == len(mesh.vertices)

    err = fidelity(out, mesh, graph, poses, fps)
    print(f"\nglTF fidelity ({suffix}, stretch={stretch}): median {np.median(err):.5%}, max {err.max():.5%} "
          "of the bbox diagonal")
    assert err.max() < (1e-5 if stretch else 0.01)     # stretch nodes: exact up to float32
    # the bend is big (60 degrees) while the error is only the non-rotation part of R_j
    assert np.linalg.norm(reference_skin(mesh, graph, poses[6]) - mesh.vertices, axis=1).max() > 0.2 * mesh.diagonal


def test_stretch_is_chosen_when_the_polar_rotation_would_cost_more_than_the_tolerance(tmp_path, capsule_take):
    mesh, graph, poses, fps = capsule_take
    rigid = bend_poses(graph, 4, np.random.default_rng(1), affine=0.0)
    assert polar_error_bound(mesh, graph, np.stack([p.rotations for p in rigid])) < 1e-9
    bound = polar_error_bound(mesh, graph, np.stack([p.rotations for p in poses]))
    # the bound holds: the polar-only file's true error is below it
    write_gltf(tmp_path / "polar.glb", mesh, graph, poses, fps, stretch=False)
    err = fidelity(tmp_path / "polar.glb", mesh, graph, poses, fps)
    assert 0 < err.max() * mesh.diagonal <= bound
    for tol, nodes in ((bound / mesh.diagonal * 1.01, graph.node_count + 2), (bound / mesh.diagonal * 0.99,
                                                                          2 * graph.node_count + 2)):
        write_gltf(tmp_path / "auto.glb", mesh, graph, poses, fps, tolerance=tol)
        assert len(GltfPlayer(tmp_path / "auto.glb").doc.nodes) == nodes


def test_stretch_factors_are_continuous_and_exact():
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(3)
    t = np.linspace(0.2, 1, 30)[:, None]     # (at t = 0, R = I: any U = W^T is an SVD)
    rot = Rotation.from_rotvec(t[:, :, None] * rng.normal(size=(1, 5, 3))).as_matrix()           # (30, 5, 3, 3)
    sym = rng.normal(size=(5, 3, 3)) * 0.3
    r = rot @ (np.eye(3) + t[:, :, None, None] * (sym + sym.transpose(0, 2, 1)))
    u, s, w = stretch_factors(r)
    np.testing.assert_allclose(np.einsum("fnij,fnj,fnjk->fnik", u, s, w), r, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(u), 1.0)
    np.testing.assert_allclose(np.linalg.det(w), 1.0)
    # consecutive keys stay close (no relabelled axes between frames)
    assert np.abs(np.diff(u, axis=0)).max() < 0.5 and np.abs(np.diff(w, axis=0)).max() < 0.5


def test_stretch_interpolates_smoothly_between_keys(tmp_path, capsule_take):
    """Between two keys a player slerps U and W and lerps s: the result stays near the blended pose."""
    mesh, graph, poses, fps = capsule_take
    write_gltf(tmp_path / "mid.glb", mesh, graph, poses, fps, stretch=True)
    player = GltfPlayer(tmp_path / "mid.glb")
    for k in range(len(poses) - 1):
        a, b = poses[k], poses[k + 1]
        blend = GraphPose(0.5 * (a.rotations + b.rotations), 0.5 * (a.translations + b.translations))
        err = np.linalg.norm(player.skin((k + 0.5) / fps) - reference_skin(mesh, graph, blend), axis=1)
        assert err.max() < 0.01 * mesh.diagonal


def test_rigid_take_is_exact(tmp_path, capsule_take):
    """With exact rotations the glTF TRS reproduces Eq. 2 up to float32 rounding."""
    mesh, graph, _, fps = capsule_take
    poses = bend_poses(graph, 5, np.random.default_rng(1), affine=0.0)
    write_gltf(tmp_path / "rigid.glb", mesh, graph, poses, fps)
    assert len(GltfPlayer(tmp_path / "rigid.glb").doc.nodes) == graph.node_count + 2     # no stretch needed
    err = fidelity(tmp_path / "rigid.glb", mesh, graph, poses, fps)
    assert err.max() < 1e-5


def test_document_structure(tmp_path, capsule_take):
    mesh, graph, poses, fps = capsule_take
    write_gltf(tmp_path / "take.glb", mesh, graph, poses, fps, name="walk", stretch=False)
    player = GltfPlayer(tmp_path / "take.glb")
    doc = player.doc
    n = graph.node_count
    assert len(doc.skins[0].joints) == n
    np.testing.assert_allclose(player.inverse_bind[:, :3, 3], -graph.nodes, atol=1e-6)
    np.testing.assert_array_equal(player.inverse_bind[:, :3, :3], np.tile(np.eye(3), (n, 1, 1)))
    assert doc.animations[0].name == "walk"
    assert len(doc.animations[0].channels) == 2 * n
    times = player.tracks[0][3]
    np.testing.assert_allclose(times, np.arange(len(poses)) / fps, atol=1e-6)
    np.testing.assert_allclose(player.weights.sum(axis=1), 1.0, atol=1e-6)
    # UVs survive (trimesh flips v for glTF's top-left origin)
    uv = player.accessor(player.primitive.attributes.TEXCOORD_0)
    np.testing.assert_allclose(uv[:, 0], mesh.uvs[:, 0], atol=1e-6)
    np.testing.assert_allclose(uv[:, 1], 1.0 - mesh.uvs[:, 1], atol=1e-6)
    normals = player.accessor(player.primitive.attributes.NORMAL)
    np.testing.assert_allclose(normals, mesh.normals, atol=1e-5)


def test_textured_material_and_colours_are_kept(tmp_path, capsule_take):
    mesh, graph, poses, fps = capsule_take
    image = Image.fromarray(np.tile(np.linspace(0, 255, 64, dtype=np.uint8)[:, None, None], (1, 64, 3)))
    material = trimesh.visual.material.PBRMaterial(baseColorTexture=image, metallicFactor=0.0,
                                                   roughnessFactor=0.7)
    colors = np.tile(np.array([[255, 0, 0, 255]], np.uint8), (len(mesh.vertices), 1))
    textured = Mesh(mesh.vertices, mesh.faces, mesh.normals, uvs=mesh.uvs, colors=colors, material=material)
    out = tmp_path / "textured.glb"
    write_gltf(out, textured, graph, poses[:2], fps)
    report = validate_gltf(out)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
    assert report["info"]["hasTextures"]
    image_info = [r for r in report["info"]["resources"] if r["pointer"].startswith("/images/")]
    assert image_info[0]["image"]["width"] == 64
    player = GltfPlayer(out)
    pbr = player.doc.materials[0].pbrMetallicRoughness
    assert pbr.baseColorTexture is not None and pbr.roughnessFactor == pytest.approx(0.7)
    np.testing.assert_allclose(player.accessor(player.primitive.attributes.COLOR_0)[:, 0], 1.0)


def test_vertex_colours_without_uvs(tmp_path, capsule_take):
    mesh, graph, poses, fps = capsule_take
    colors = np.tile(np.array([[0, 128, 255, 255]], np.uint8), (len(mesh.vertices), 1))
    plain = Mesh(mesh.vertices, mesh.faces, mesh.normals, colors=colors)
    out = tmp_path / "colours.gltf"
    write_gltf(out, plain, graph, poses[:3], fps)
    assert validate_gltf(out)["issues"]["numErrors"] == 0
    player = GltfPlayer(out)
    c = player.accessor(player.primitive.attributes.COLOR_0)
    np.testing.assert_allclose(c[0, :3], [0, 128 / 255, 1.0], atol=1e-6)


def _numpy_stretch_factors(rotations):
    """`stretch_factors` as numpy products frame by frame: the reference the kernel must match bit for bit."""
    from kinetre.svd3 import det3, svd3
    u, s, w = svd3(rotations)
    du, dw = np.sign(det3(u)), np.sign(det3(w))
    du[du == 0], dw[dw == 0] = 1.0, 1.0
    u[..., :, 2] *= du[..., None]
    w[..., 2, :] *= dw[..., None]
    s[..., 2] *= du * dw
    signed = []
    for order in itertools.permutations(range(3)):  # in the library's order: it breaks ties by the first
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[list(order), range(3)] = signs
            signed.append(m)
    cube = np.array([m for m in signed if np.linalg.det(m) > 0])  # the 24 rotations among them
    for k in range(1, rotations.shape[0]):
        near = u[k].transpose(0, 2, 1) @ u[k - 1] + w[k] @ w[k - 1].transpose(0, 2, 1)
        m = cube[np.argmax(near.reshape(-1, 9) @ cube.reshape(24, 9).T, axis=1)]
        u[k] = u[k] @ m
        w[k] = m.transpose(0, 2, 1) @ w[k]
        s[k] = np.einsum("nji,nj->ni", m * m, s[k])
    return u, s, w


def test_stretch_factors_are_numpys_frame_by_frame_products_bit_for_bit():
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(7)
    r = Rotation.random(30 * 40, random_state=8).as_matrix().reshape(30, 40, 3, 3)
    rotations = r * rng.uniform(0.5, 1.5, (30, 40, 1, 3))
    rotations[:, :4] = np.eye(3)                 # nodes that never move: exact zeros, tied closeness
    rotations[:, 4:7] = np.diag([2.0, 2.0, 1.0])  # repeated singular values
    rotations[3:6, 7] = 0.0                      # a collapsed node
    rotations[:, 8] *= -1.0                      # reflections
    for got, want in zip(stretch_factors(rotations), _numpy_stretch_factors(rotations)):
        assert np.array_equal(got, want) and np.array_equal(np.signbit(got), np.signbit(want))


def test_quaternions_are_scipys_bit_for_bit():
    # random rotations, the axis-aligned half turns (each of Shepperd's four cases), the polar and stretch
    # factors of a real bend; then matrices that are not rotations, which scipy itself converts
    from scipy.spatial.transform import Rotation
    turns = [np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1]),
             np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])]
    rotations = np.concatenate([Rotation.random(20000, random_state=3).as_matrix(), turns])
    r = Rotation.random(600, random_state=4).as_matrix().reshape(20, 30, 3, 3)
    stretched = r * np.random.default_rng(5).uniform(0.7, 1.4, (20, 30, 1, 3))
    u, _, w = stretch_factors(stretched)
    def scipys(m):
        return Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat().reshape(m.shape[:-2] + (4,))
    for m in (rotations, polar_rotations(stretched), u, w):
        got = matrix_quaternions(m)
        assert got.shape == m.shape[:-2] + (4,) and np.array_equal(got, scipys(m))
    for m in (rotations[:50] * 1.001, rotations[:50] + 1e-9):  # scipy re-orthogonalises these first
        assert np.array_equal(matrix_quaternions(m), scipys(m))
    with pytest.raises(ValueError):  # a reflection: scipy's own refusal
        matrix_quaternions(np.diag([1.0, 1, -1])[None])


def test_polar_rotation_of_a_stretched_rotation():
    rng = np.random.default_rng(0)
    from scipy.spatial.transform import Rotation
    q = Rotation.random(5, random_state=1).as_matrix()
    s = rng.normal(size=(5, 3, 3)) * 0.05
    m = q @ (np.eye(3) + s + s.transpose(0, 2, 1))
    np.testing.assert_allclose(polar_rotations(m), q, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(polar_rotations(-m[:1])), 1.0)


def test_skin_weights_are_normalised_in_float32(capsule_take):
    _, graph, _, _ = capsule_take
    joints, weights = skin_weights(graph)
    assert joints.dtype == np.uint8 and weights.dtype == np.float32
    assert np.abs(weights.sum(axis=1, dtype=np.float32) - 1).max() <= 2 * np.finfo(np.float32).eps
    for row_j, row_w in zip(joints, weights):
        nonzero = row_j[row_w > 0]
        assert len(set(nonzero.tolist())) == len(nonzero)


def test_more_than_255_nodes_use_16_bit_joints(tmp_path, capsule_take):
    mesh, _, _, fps = capsule_take
    graph = synthetic_graph(mesh, 300, np.random.default_rng(0))
    poses = bend_poses(graph, 3, np.random.default_rng(0))
    write_gltf(tmp_path / "many.glb", mesh, graph, poses, fps)
    report = validate_gltf(tmp_path / "many.glb")
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    player = GltfPlayer(tmp_path / "many.glb")
    assert player.doc.accessors[player.primitive.attributes.JOINTS_0].componentType == 5123   # UNSIGNED_SHORT
    assert fidelity(tmp_path / "many.glb", mesh, graph, poses, fps).max() < 1e-5


def test_bad_inputs_raise_export_errors(tmp_path, capsule_take):
    mesh, graph, poses, fps = capsule_take
    with pytest.raises(ExportError, match=r"take\.fbx: .*\.glb or \.gltf"):
        write_gltf(tmp_path / "take.fbx", mesh, graph, poses, fps)
    with pytest.raises(ExportError, match="no frames"):
        write_gltf(tmp_path / "a.glb", mesh, graph, [], fps)
    with pytest.raises(ExportError, match="fps"):
        write_gltf(tmp_path / "a.glb", mesh, graph, poses, 0.0)
    nan_pose = GraphPose(poses[0].rotations, np.full_like(poses[0].translations, np.nan))
    with pytest.raises(ExportError, match="frame 1 is not finite"):
        write_gltf(tmp_path / "a.glb", mesh, graph, [poses[0], nan_pose], fps)
    small = synthetic_graph(Mesh(mesh.vertices[:100], mesh.faces[:10], mesh.normals[:100]), 8,
                            np.random.default_rng(0))
    with pytest.raises(ExportError, match="skins 100 vertices but the mesh has"):
        write_gltf(tmp_path / "a.glb", mesh, small, poses, fps)
    (tmp_path / "file").write_text("x")
    with pytest.raises(ExportError, match="cannot write"):
        write_gltf(tmp_path / "file" / "a.glb", mesh, graph, poses, fps)
