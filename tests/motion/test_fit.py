"""Placing a take in a mesh: scale, facing, centring, grounding, and poses back in the mesh's units."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import kinetre
from kinetre.errors import BadMotionError
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.motion.fit import facing, fit_take, yaw_rotation
from kinetre.motion.source import Take
from synthetic import tpose


def box_mesh(extents=(40.0, 120.0, 30.0), centre=(100.0, 50.0, -20.0)) -> kinetre.Mesh:
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(centre)
    return mesh_from_trimesh(box, "box")


def take_facing(degrees: float, frames: int = 3) -> Take:
    sk = tpose(1.7).transformed(1.0, yaw_rotation(degrees), (5.0, 0.3, -2.0))
    pos = np.repeat(sk.positions[None], frames, axis=0)
    pos[1:, :, 0] += np.arange(1, frames)[:, None] * 0.1  # walks along x
    return Take(kinetre.KINECT20, pos, np.ones(pos.shape[:2], bool), 30.0, "walk")


def test_facing_of_a_tpose():
    np.testing.assert_allclose(facing(tpose()), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(facing(tpose().transformed(1.0, yaw_rotation(90.0))), [1, 0, 0], atol=1e-12)


@pytest.mark.parametrize("turned", [-90.0, 0.0, 135.0])
def test_bind_frame_is_scaled_faced_centred_and_grounded(turned):
    mesh = box_mesh()
    take = take_facing(turned)
    fit = fit_take(take, mesh)
    k = fit.mesh_scale
    assert k == pytest.approx(tpose(1.7).height / 120.0)  # joint height (head joint, not the crown)
    bind = fit.skeleton(take.frame(0))
    np.testing.assert_allclose(facing(bind), [0, 0, 1], atol=1e-9)
    lo, hi = mesh.bounds * k
    assert bind.positions[:, 1].min() == pytest.approx(lo[1])
    assert bind.height == pytest.approx(hi[1] - lo[1])  # as tall as the scaled mesh
    mid = 0.5 * (bind.positions.min(axis=0) + bind.positions.max(axis=0))
    np.testing.assert_allclose(mid[[0, 2]], (0.5 * (lo + hi))[[0, 2]], atol=1e-9)
    # every frame moves rigidly with the bind frame: the walk along x is kept (turned with the body)
    moved = fit.take(take).positions
    step = np.linalg.norm(moved[1, 0] - moved[0, 0])
    assert step == pytest.approx(0.1)
    assert fit.output_scale == pytest.approx(1.0 / k)


def test_yaw_and_fit_mesh():
    mesh = box_mesh()
    fit = fit_take(take_facing(0.0), mesh, yaw=90.0, fit_mesh=True)
    np.testing.assert_allclose(facing(fit.skeleton(take_facing(0.0).frame(0))), [1, 0, 0], atol=1e-9)
    assert fit.output_scale == 1.0
    resized = fit.mesh(mesh)
    assert np.ptp(resized.vertices[:, 1]) == pytest.approx(tpose(1.7).height)
    np.testing.assert_array_equal(resized.normals, mesh.normals)


def test_bind_frame_choice():
    take = take_facing(0.0)
    a = fit_take(take, box_mesh(), bind_frame=0)
    b = fit_take(take, box_mesh(), bind_frame=2)
    # frame 2 stands 0.2 m further along x: the placement shifts it back onto the mesh centre
    assert a.translation[0] - b.translation[0] == pytest.approx(0.2)


def test_output_pose_matches_skinning_in_mesh_units(body):
    # skinning the solve-frame mesh then scaling back == skinning the original mesh with the output pose
    mesh = dataclass_scaled(body, 37.0)
    graph = kinetre.build_graph(mesh, nodes=48, seed=0)
    fit = fit_take(take_facing(30.0), mesh)
    rng = np.random.default_rng(0)
    n = graph.node_count
    rot = np.eye(3) + 0.1 * rng.normal(size=(n, 3, 3))
    pose = kinetre.GraphPose(rot, 0.05 * rng.normal(size=(n, 3)))
    solve = kinetre.skin(fit.mesh(mesh), fit.graph(graph), pose)
    out = kinetre.skin(mesh, graph, fit.output_pose(pose))
    np.testing.assert_allclose(solve * fit.output_scale, out, atol=1e-9 * mesh.diagonal)


def dataclass_scaled(mesh, s):
    import dataclasses
    return dataclasses.replace(mesh, vertices=mesh.vertices * s)


def test_generic_skeleton_keeps_its_orientation():
    model = kinetre.SkeletonModel("bvh:dog", ("Pelvis", "Head", "Paw"), (-1, 0, 0))
    pos = np.array([[[0.0, 1.0, 0.0], [0.0, 1.2, 1.0], [0.0, 0.0, 0.0]]])
    take = Take(model, pos, np.ones((1, 3), bool), 30.0, "dog")
    fit = fit_take(take, box_mesh())
    np.testing.assert_allclose(fit.rotation, np.eye(3), atol=1e-12)
    assert fit_take(take, box_mesh(), yaw=180.0).rotation[2, 2] == pytest.approx(-1.0)


def test_bind_frame_without_height():
    model = kinetre.SkeletonModel("flat", ("A", "B"), (-1, 0))
    take = Take(model, np.array([[[0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]]), np.ones((1, 2), bool), 30.0, "flat.bvh")
    with pytest.raises(BadMotionError, match="flat.bvh: bind frame 0 is flat"):
        fit_take(take, box_mesh())
    lone = Take(model, np.array([[[0.0, 1.0, 0.0], [np.nan] * 3]]), np.ones((1, 2), bool), 30.0, "lone")
    with pytest.raises(BadMotionError, match="tracks 1 joint"):
        fit_take(lone, box_mesh())
