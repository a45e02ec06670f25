"""A source that already stands inside the mesh is detected from the shapes and driven where it stands."""
import numpy as np

import kinetre
from kinetre.motion.in_place import stands_inside
from kinetre.motion.take import Take
from kinetre.skeleton.models import KINECT20, Skeleton, SkeletonModel
from synthetic import capsule_body, tpose

STICK = SkeletonModel("stick", KINECT20.joints, KINECT20.parents)  # a person's joints under another model


def _stick_take(height=1.0, centre=(3.0, 0.5, -2.0), frames=3) -> Take:
    """A T-pose of a non-Kinect model standing away from the origin, its left arm raised over the frames."""
    bind = tpose(height, centre).positions
    pos = np.repeat(bind[None], frames, axis=0)
    shoulder, elbow = KINECT20.index("ShoulderLeft"), KINECT20.index("ElbowLeft")
    for f in range(frames):
        a = np.radians(30.0 * f)
        for j in ("ElbowLeft", "WristLeft", "HandLeft"):
            k = KINECT20.index(j)
            d = bind[k] - bind[shoulder]
            pos[f, k] = bind[shoulder] + [d[0] * np.cos(a), d[0] * np.sin(a), d[2]]
    assert elbow >= 0
    return Take(STICK, pos, np.ones(pos.shape[:2], bool), 30.0, "stick")


def test_a_skeleton_inside_its_mesh_is_detected_and_a_moved_or_shrunk_one_is_not():
    take = _stick_take()
    mesh = capsule_body(Skeleton(STICK, take.positions[0], take.tracked[0]), radius=0.03)
    assert stands_inside(take, mesh)
    assert not stands_inside(take.transformed(1.0, None, [0.0, 0.5, 0.0]), mesh)  # half its height up
    assert not stands_inside(take.transformed(1.0, None, [0.4, 0.0, 0.0]), mesh)  # beside it
    centre = take.positions[0].mean(axis=0)
    assert not stands_inside(take.transformed(0.4, None, 0.6 * centre), mesh)  # shrunk inside the torso


def test_animate_drives_a_standing_source_where_it_stands():
    take = _stick_take()
    mesh = capsule_body(Skeleton(STICK, take.positions[0], take.tracked[0]), radius=0.03)
    result = kinetre.animate(mesh, take, kinetre.AnimateSettings(nodes=96))
    p = result.placement
    assert p.method == "in place"
    assert np.allclose(p.rotation, np.eye(3)) and np.allclose(p.translation, 0.0)
    assert p.skeleton_scale == p.mesh_scale  # skeleton and mesh scaled alike: no fit
    # the output skeleton is the input, untouched, and the bind pose attached all 20 joints
    np.testing.assert_allclose(result.take.positions, take.positions, atol=1e-12)
    assert len(result.rig.attached_joints[0]) == 20
    # the raised hand's mesh follows the hand: the vertices nearest it at bind move with it
    hand = KINECT20.index("HandLeft")
    near = np.linalg.norm(mesh.vertices - take.positions[0, hand], axis=1) < 0.04
    moved = kinetre.skin(result.mesh, result.graph, result.poses[2])[near].mean(axis=0)
    target = take.positions[2, hand] + (mesh.vertices[near].mean(axis=0) - take.positions[0, hand])
    assert np.linalg.norm(moved - target) < 0.05 * np.linalg.norm(take.positions[2, hand] - take.positions[0, hand])


def test_a_mapped_take_drives_with_its_own_skeleton_when_that_stands_inside():
    native = _stick_take()
    kinect = Take(KINECT20, native.positions, native.tracked, native.fps, "mapped", native=native)
    mesh = capsule_body(Skeleton(STICK, native.positions[0], native.tracked[0]), radius=0.03)
    result = kinetre.animate(mesh, kinect, kinetre.AnimateSettings(nodes=96))
    assert result.placement.method == "in place" and result.take.model is STICK
    # a turn asked for keeps the fitting path, on the mapped skeleton
    turned = kinetre.animate(mesh, kinect, kinetre.AnimateSettings(nodes=96, yaw=0.0, solve=False))
    assert turned.placement.method == "height" and turned.take.model == KINECT20
