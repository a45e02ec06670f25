"""Bone twist from the source's own joint rotations: a rod whose bone rolls about itself."""
import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

import kinetre
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.skeleton.attach import constraint_targets
from kinetre.skeleton.models import Skeleton, SkeletonModel

ROD = SkeletonModel("rod", ("base", "top"), (-1, 0))
BIND = np.array([[0.0, 0.0, 0.0], [0.0, 0.6, 0.0]])


def _rod(roll_degrees: float | None) -> Skeleton:
    """The rod's joints unmoved; with a roll, the bone frame carrying the top turned about the bone (+Y)."""
    if roll_degrees is None:
        return Skeleton(ROD, BIND, np.ones(2, bool))
    frames = np.stack([np.eye(3), Rotation.from_euler("y", roll_degrees, degrees=True).as_matrix()])
    return Skeleton(ROD, BIND, np.ones(2, bool), frames)


def _cylinder_graph():
    tm = trimesh.creation.cylinder(radius=0.05, height=0.6, sections=24)
    tm.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    tm.apply_translation([0.0, 0.3, 0.0])
    tm = tm.subdivide().subdivide()
    mesh = mesh_from_trimesh(tm, "rod")
    return mesh, kinetre.build_graph(mesh, nodes=64)


def test_bone_samples_follow_the_sources_roll():
    mesh, graph = _cylinder_graph()
    rig = kinetre.attach(graph, _rod(0.0))
    att = rig.attachments[0]
    samples = att.bone >= 0
    assert samples.sum() >= 8
    roll = Rotation.from_euler("y", 50.0, degrees=True).as_matrix()
    q, ok = constraint_targets(att, _rod(50.0))
    assert ok.all()
    np.testing.assert_allclose(q[samples], att.constraints.points[samples] @ roll.T, atol=1e-12)
    # positions alone cannot show a roll: the samples stay (the minimal rotation is the identity)
    q_still, _ = constraint_targets(att, Skeleton(ROD, BIND, np.ones(2, bool)))
    np.testing.assert_allclose(q_still[samples], att.constraints.points[samples], atol=1e-12)
    # the rig's per-frame path (all skeletons stacked) gives the same targets
    np.testing.assert_allclose(rig.targets([_rod(50.0)])[0], q, atol=1e-12)


def test_a_rolling_bone_rolls_the_rod():
    mesh, graph = _cylinder_graph()
    rig = kinetre.attach(graph, _rod(0.0))
    roll = Rotation.from_euler("y", 60.0, degrees=True).as_matrix()
    for degrees in range(10, 61, 10):  # rolled over a few frames, as in a clip
        pose = rig.solve(_rod(float(degrees)))
    moved = kinetre.skin(mesh, graph, pose)
    expected = mesh.vertices @ roll.T
    travel = np.linalg.norm(expected - mesh.vertices, axis=1).mean()  # about 5 cm at 60 degrees
    assert travel > 0.04
    assert np.linalg.norm(moved - expected, axis=1).mean() < 0.15 * travel
    rig.reset()
    still = kinetre.skin(mesh, graph, rig.solve(_rod(None)))
    assert np.linalg.norm(still - mesh.vertices, axis=1).mean() < 0.01 * travel
