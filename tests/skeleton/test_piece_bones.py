"""A skeleton standing inside a multi-part mesh carries each piece by the bones that run through it: a hand
raised beside a separate head piece does not drag the head along."""
import numpy as np

import trimesh

import kinetre
from kinetre.graph.pieces import vertex_pieces
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.skeleton.models import Skeleton, SkeletonModel
from kinetre.skeleton.piece_bones import piece_bones

BODY = SkeletonModel("body", ("root", "head", "head_tip", "shoulder", "hand"), (-1, 0, 1, 0, 3))
HEAD_BONE, ARM_BONE = 1, 3  # rows of BODY.bones: head -> head_tip, shoulder -> hand
BIND = np.array([[0.0, 1.0, 0.0], [0.0, 1.52, 0.0], [0.0, 1.68, 0.0], [0.3, 1.0, 0.0], [0.17, 1.6, 0.0]])


def _pose(hand: np.ndarray) -> Skeleton:
    pos = BIND.copy()
    pos[4] = hand
    return Skeleton(BODY, pos, np.ones(5, bool))


def _head_arm_bolt() -> kinetre.Mesh:
    """A head sphere round the head bone, an arm capsule round the arm bone whose hand end stops 4 cm from
    the head, and a small bolt just above the head (no bone runs through it): three separate pieces."""
    head = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    head.apply_translation([0.0, 1.6, 0.0])
    a, b = BIND[3], BIND[4]
    arm = trimesh.creation.capsule(height=float(np.linalg.norm(b - a)), radius=0.03, count=[12, 12])
    arm.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], (b - a) / np.linalg.norm(b - a)))
    arm.apply_translation(0.5 * (a + b))
    arm = arm.subdivide_to_size(0.02)  # vertices along the body too, not only on the caps
    bolt = trimesh.creation.icosphere(subdivisions=1, radius=0.015)
    bolt.apply_translation([0.0, 1.72, 0.0])  # 5 mm above the head's top
    return mesh_from_trimesh(trimesh.util.concatenate([head, arm, bolt]), "head_arm_bolt")


def test_each_piece_is_carried_by_the_bones_through_it():
    mesh = _head_arm_bolt()
    pieces = vertex_pieces(mesh.vertices, mesh.faces)
    assert len(np.unique(pieces)) == 3
    graph = kinetre.build_graph(mesh, nodes=128)
    bind = _pose(BIND[4])
    allowed = piece_bones(graph, bind, np.ones(5, bool))
    piece_of = {name: int(pieces[np.argmin(np.linalg.norm(mesh.vertices - p, axis=1))])
                for name, p in (("head", [0.0, 1.5, 0.0]), ("arm", [0.3, 1.0, 0.0]), ("bolt", [0.0, 1.735, 0.0]))}
    assert len(set(piece_of.values())) == 3
    assert allowed[piece_of["head"], HEAD_BONE] and not allowed[piece_of["head"], ARM_BONE]
    assert allowed[piece_of["arm"], ARM_BONE] and not allowed[piece_of["arm"], HEAD_BONE]
    # no bone runs through the bolt: any bone may carry it, as in a one-piece mesh (its nearest is the head's)
    assert allowed[piece_of["bolt"]].all()


def test_a_hand_beside_the_head_leaves_the_head_still():
    mesh = _head_arm_bolt()
    pieces = vertex_pieces(mesh.vertices, mesh.faces)
    graph = kinetre.build_graph(mesh, nodes=128)
    rig = kinetre.attach(graph, _pose(BIND[4]), node_bones=True, rigid=True)
    # the arm swings its hand down and out, away from the head; the head bone stays
    lowered = _pose(BIND[3] + 0.62 * np.array([0.7, -0.714, 0.0]))
    moved = kinetre.skin(mesh, graph, rig.solve(lowered))
    arm = pieces == pieces[np.argmin(np.linalg.norm(mesh.vertices - BIND[3], axis=1))]
    assert np.linalg.norm(moved[arm] - mesh.vertices[arm], axis=1).max() > 0.5  # the arm swung
    still = ~arm
    assert np.linalg.norm(moved[still] - mesh.vertices[still], axis=1).max() < 1e-3  # head and bolt stayed
