"""Sphere packing (KinÊtre paper, "Physics-based Interactions"): every vertex covered, radius 4 × mean
edge, deterministic, centres skinned."""
import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

import kinetre
from kinetre.deform.pose import GraphPose
from kinetre.physics.spheres import mean_edge_length, pack_spheres, sphere_centres

MESHES = ["spot.obj", "armadillo.obj", "camelhead.off", "teapot.obj", "sphereWithHole.stl",
          "elephant_loop3_large.ply.gz"]


def uncovered(mesh, packing) -> int:
    """Vertices farther than the radius from every sphere centre."""
    d, _ = cKDTree(mesh.vertices[packing.centres]).query(mesh.vertices)
    return int(np.sum(d > packing.radius * (1 + 1e-12)))


@pytest.fixture(scope="module", params=MESHES)
def shared_mesh(request, data_dir):
    return kinetre.load_mesh(data_dir / "meshes" / request.param)


def test_paper_rule_covers_every_vertex(shared_mesh):
    p = pack_spheres(shared_mesh)
    assert uncovered(shared_mesh, p) == 0
    assert p.radius == pytest.approx(4 * mean_edge_length(shared_mesh)) and p.factor == 4.0
    assert len(np.unique(p.centres)) == p.count
    # greedy: no centre lies inside an earlier sphere (it would have been covered already)
    centres = shared_mesh.vertices[p.centres]
    for i in range(1, min(p.count, 300)):
        assert np.min(np.linalg.norm(centres[:i] - centres[i], axis=1)) > p.radius


def test_budget_grows_the_radius_and_still_covers(shared_mesh):
    p = pack_spheres(shared_mesh, max_spheres=64)
    assert p.count <= 64 and uncovered(shared_mesh, p) == 0
    paper = pack_spheres(shared_mesh)
    if paper.count <= 64:
        assert np.array_equal(p.centres, paper.centres)  # under budget: the paper's packing, untouched
    else:
        assert p.radius > paper.radius


def test_mean_edge_of_a_unit_square():
    # two triangles of a unit square: 4 sides of 1 and a diagonal of sqrt(2), the shared edge counted once
    mesh = kinetre.Mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float),
                        np.array([[0, 1, 2], [0, 2, 3]], np.int32), np.tile([0, 0, 1.0], (4, 1)))
    assert mean_edge_length(mesh) == pytest.approx((4 + np.sqrt(2)) / 5)
    p = pack_spheres(mesh, factor=0.1)  # smaller than any edge: one sphere per vertex
    assert sorted(p.centres) == [0, 1, 2, 3]


def test_same_seed_same_spheres(data_dir):
    mesh = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    a, b, c = pack_spheres(mesh, seed=7), pack_spheres(mesh, seed=7), pack_spheres(mesh, seed=8)
    assert np.array_equal(a.centres, b.centres)
    assert not np.array_equal(a.centres, c.centres)


def test_centres_follow_the_skinned_surface(data_dir):
    mesh = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    graph = kinetre.build_graph(mesh, nodes=64, seed=0)
    p = pack_spheres(mesh)
    rng = np.random.default_rng(1)
    rotations = Rotation.from_rotvec(0.3 * rng.standard_normal((graph.node_count, 3))).as_matrix()
    pose = GraphPose(rotations, 0.05 * rng.standard_normal((graph.node_count, 3)))
    moved = sphere_centres(p, mesh, graph, pose)
    assert np.allclose(moved, kinetre.skin(mesh, graph, pose)[p.centres], atol=1e-12)
    assert np.max(np.linalg.norm(moved - mesh.vertices[p.centres], axis=1)) > 0.05  # it did move


def test_bad_arguments(data_dir):
    mesh = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    with pytest.raises(ValueError, match="factor"):
        pack_spheres(mesh, factor=0)
    with pytest.raises(ValueError, match="max_spheres"):
        pack_spheres(mesh, max_spheres=0)
