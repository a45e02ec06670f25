"""Attachment: joints within 10 cm, bone cylinders with normals, several skeletons, clear refusals."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kinetre
from kinetre.errors import AttachError
from kinetre.skeleton.attach import bone_samples
from kinetre.skeleton.models import KINECT20, Skeleton
from synthetic import tpose


def test_bone_samples_on_cylinder_with_outward_normals():
    a, b = np.zeros(3), np.array([0.0, 0.3, 0.0])
    p, n = bone_samples(a, b, 0.04)
    assert p.shape == (16, 3)
    radial = p - np.outer(p[:, 1] / 0.3, b)
    assert np.allclose(np.linalg.norm(radial, axis=1), 0.04)
    assert np.allclose(radial / 0.04, n)
    assert len(np.unique(np.round(p[:, 1], 6))) == 4  # four rings along the bone


def test_tpose_inside_body_attaches_every_joint(body_graph):
    rig = kinetre.attach(body_graph, tpose())
    assert len(rig.attached_joints[0]) == 20
    assert rig.attachments[0].bone_sample_count > 100
    assert len(rig.nodes_used) > 0.5 * body_graph.node_count


def test_far_skeleton_is_refused_with_distance(body_graph):
    with pytest.raises(AttachError, match=r"no joint or bone is within 10 cm.*nearest joint is 3\.\d\d m away"):
        kinetre.attach(body_graph, tpose(centre=(5.0, 0, 0)))


def test_untracked_skeleton_is_refused(body_graph):
    s = tpose()
    with pytest.raises(AttachError, match="no joint of the skeleton is tracked"):
        kinetre.attach(body_graph, Skeleton(KINECT20, s.positions, np.zeros(20, bool)))


def test_subset_limits_attachment(body_graph):
    rig = kinetre.attach(body_graph, tpose(), subset="left arm")
    joints = {KINECT20.joints[j] for j in rig.attached_joints[0]}
    assert joints == {"ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft"}


def test_rigid_skeleton_motion_moves_mesh_rigidly(body, body_graph):
    rig = kinetre.attach(body_graph, tpose())
    rot = Rotation.from_euler("xyz", [10, 35, -5], degrees=True).as_matrix()
    moved = tpose().transformed(rotation=rot, translation=(0.2, 0.0, -0.1))
    pose = None
    for _ in range(3):  # warm-started frames of the same target
        pose = rig.solve(moved)
    v = kinetre.skin(body, body_graph, pose)
    assert np.abs(v - (body.vertices @ rot.T + [0.2, 0.0, -0.1])).max() < 1e-5


def test_arm_raise_moves_arm_not_legs(body, body_graph):
    rig = kinetre.attach(body_graph, tpose())
    s = tpose()
    pos = s.positions.copy()
    sh = KINECT20.index("ShoulderLeft")
    arm = [KINECT20.index(j) for j in ("ElbowLeft", "WristLeft", "HandLeft")]
    up = Rotation.from_euler("z", 60, degrees=True).as_matrix()
    pos[arm] = (pos[arm] - pos[sh]) @ up.T + pos[sh]
    pose = rig.solve(Skeleton(KINECT20, pos, s.tracked))
    assert rig.last_report.iterations <= 10
    v = kinetre.skin(body, body_graph, pose)
    hand = np.argmin(np.linalg.norm(body.vertices - s.positions[KINECT20.index("HandLeft")], axis=1))
    foot = np.argmin(np.linalg.norm(body.vertices - s.positions[KINECT20.index("FootRight")], axis=1))
    assert np.linalg.norm(v[hand] - pos[KINECT20.index("HandLeft")]) < 0.08
    assert np.linalg.norm(v[foot] - body.vertices[foot]) < 0.01


def test_two_skeletons_drive_one_mesh(body, body_graph):
    # person A possesses the left half, person B the right half (two users, one horse)
    a, b = tpose(), tpose()
    rig = kinetre.attach(body_graph, [a, b], subset=[["left arm", "left leg"], ["right arm", "right leg"]])
    assert rig.attached_joints[0].size == 8 and rig.attached_joints[1].size == 8
    lift = np.array([0, 0.1, 0])
    pose = rig.solve([a.transformed(translation=lift), b])
    v = kinetre.skin(body, body_graph, pose)
    hand_l = np.argmin(np.linalg.norm(body.vertices - a.positions[KINECT20.index("HandLeft")], axis=1))
    hand_r = np.argmin(np.linalg.norm(body.vertices - a.positions[KINECT20.index("HandRight")], axis=1))
    assert v[hand_l, 1] - body.vertices[hand_l, 1] > 0.07
    assert abs(v[hand_r, 1] - body.vertices[hand_r, 1]) < 0.03


def test_tracking_loss_holds_last_pose(body, body_graph):
    rig = kinetre.attach(body_graph, tpose())
    p1 = rig.solve(tpose().transformed(translation=(0.05, 0, 0)))
    lost = Skeleton(KINECT20, np.full((20, 3), np.nan), np.ones(20, bool))
    p2 = rig.solve(lost)
    assert np.array_equal(p1.translations, p2.translations) and np.array_equal(p1.rotations, p2.rotations)


def test_nan_joint_drops_out(body, body_graph):
    rig = kinetre.attach(body_graph, tpose())
    s = tpose().transformed(translation=(0.05, 0, 0))
    pos = s.positions.copy()
    pos[KINECT20.index("HandLeft")] = np.inf
    pose = rig.solve(Skeleton(KINECT20, pos, s.tracked))
    assert np.all(np.isfinite(pose.translations))
    assert np.allclose(pose.node_matrices(body_graph.nodes)[:, :3, 3], [0.05, 0, 0], atol=1e-3)


def test_a_standing_skeletons_bone_samples_pull_only_on_the_nodes_that_bone_carries():
    """A leg (thigh and shin meeting at the knee, one piece of mesh): with node bones every node follows its
    own bone, and a bone's cylinder samples near the knee must not also pull on the other bone's nodes."""
    import trimesh

    from kinetre.mesh.load import mesh_from_trimesh
    from kinetre.skeleton.attach import attach_skeleton, nearest_bones
    from kinetre.skeleton.models import SkeletonModel

    leg = SkeletonModel("leg", ("hip", "knee", "ankle"), (-1, 0, 1))
    pos = np.array([[0.0, 0.9, 0.0], [0.0, 0.45, 0.0], [0.0, 0.0, 0.0]])
    box = trimesh.creation.box(bounds=[[-0.06, -0.02, -0.06], [0.06, 0.92, 0.06]]).subdivide_to_size(0.02)
    mesh = mesh_from_trimesh(box, "leg")
    graph = kinetre.build_graph(mesh, nodes=96)
    skeleton = Skeleton(leg, pos, np.ones(3, bool))
    att = attach_skeleton(graph, skeleton, np.ones(3, bool), node_bones=True)
    carriers = nearest_bones(graph.nodes, skeleton, np.ones(3, bool))
    assert set(carriers) == {0, 1}
    node_rows = int((carriers >= 0).sum())  # one constraint per carried node, after the samples
    samples = np.flatnonzero(att.bone[:len(att.bone) - node_rows] >= 0)
    assert set(att.bone[samples]) == {0, 1}  # both bones have samples
    c = att.constraints
    for row in samples:
        used = c.nodes[row][c.weights[row] > 0]
        assert (carriers[used] == att.bone[row]).all(), (row, att.bone[row], carriers[used])
