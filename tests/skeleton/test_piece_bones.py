"""A skeleton standing inside a multi-part mesh carries each piece by the bones that run through it: a hand
raised beside a separate head piece does not drag the head along, and a piece no bone runs through (a bolt,
a thumb) rides on the piece it touches."""
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


def _head_and_arm() -> list:
    """A head sphere round the head bone and an arm capsule round the arm bone whose hand end stops 4 cm from
    the head."""
    head = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    head.apply_translation([0.0, 1.6, 0.0])
    a, b = BIND[3], BIND[4]
    arm = trimesh.creation.capsule(height=float(np.linalg.norm(b - a)), radius=0.03, count=[12, 12])
    arm.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], (b - a) / np.linalg.norm(b - a)))
    arm.apply_translation(0.5 * (a + b))
    arm = arm.subdivide_to_size(0.02)  # vertices along the body too, not only on the caps
    return [head, arm]


def _head_arm_bolt() -> kinetre.Mesh:
    """`_head_and_arm` and a small bolt just above the head (no bone runs through it): three separate pieces."""
    bolt = trimesh.creation.icosphere(subdivisions=1, radius=0.015)
    bolt.apply_translation([0.0, 1.72, 0.0])  # 5 mm above the head's top
    return mesh_from_trimesh(trimesh.util.concatenate(_head_and_arm() + [bolt]), "head_arm_bolt")


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


def test_with_the_mesh_a_piece_no_bone_runs_through_takes_the_bones_of_the_piece_it_touches():
    mesh = _head_arm_bolt()
    pieces = vertex_pieces(mesh.vertices, mesh.faces)
    graph = kinetre.build_graph(mesh, nodes=128)
    allowed = piece_bones(graph, _pose(BIND[4]), np.ones(5, bool), mesh)
    head, arm, bolt = (int(pieces[np.argmin(np.linalg.norm(mesh.vertices - p, axis=1))])
                       for p in ([0.0, 1.5, 0.0], [0.3, 1.0, 0.0], [0.0, 1.735, 0.0]))
    # the winding number of each piece's own triangles: the head bone in the head, the arm bone in the arm
    assert allowed[head, HEAD_BONE] and not allowed[head, ARM_BONE]
    assert allowed[arm, ARM_BONE] and not allowed[arm, HEAD_BONE]
    # the bolt sits 5 mm above the head and 12 cm from the hand: it is the head's
    assert (allowed[bolt] == allowed[head]).all()


def _head_arm_thumb() -> kinetre.Mesh:
    """`_head_and_arm` and a thumb: a small sphere fixed to the side of the hand that faces the head, its far
    side 1.7 cm from the head and well within the head bone's attachment reach."""
    thumb = trimesh.creation.icosphere(subdivisions=2, radius=0.012)
    thumb.apply_translation(BIND[4] + [-0.03 - 0.011, 0.0, 0.0])  # 1 mm into the hand's surface
    return mesh_from_trimesh(trimesh.util.concatenate(_head_and_arm() + [thumb]), "head_arm_thumb")


def _rigid_fit_residual(a: np.ndarray, b: np.ndarray, others: np.ndarray, moved_others: np.ndarray) -> float:
    """Largest distance of `moved_others` from `others` moved by the best rigid motion taking a to b."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    r = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
    return float(np.linalg.norm((others - ca) @ r + cb - moved_others, axis=1).max())


def test_a_thumb_beside_the_head_follows_the_hand_it_is_fixed_to():
    mesh = _head_arm_thumb()
    pieces = vertex_pieces(mesh.vertices, mesh.faces)
    assert len(np.unique(pieces)) == 3
    graph = kinetre.build_graph(mesh, nodes=128)
    thumb = pieces == np.bincount(pieces).argmin()
    arm = pieces == pieces[np.argmin(np.linalg.norm(mesh.vertices - BIND[3], axis=1))]
    assert np.linalg.norm(mesh.vertices[thumb].mean(axis=0) - (BIND[4] - [0.041, 0.0, 0.0])) < 1e-3
    assert (graph.pieces == pieces[thumb][0]).sum() >= 1  # the thumb has nodes of its own to be pulled at
    rig = kinetre.attach(graph, _pose(BIND[4]), node_bones=True, rigid=True, mesh=mesh)
    lowered = _pose(BIND[3] + 0.62 * np.array([0.7, -0.714, 0.0]))
    moved = kinetre.skin(mesh, graph, rig.solve(lowered))
    assert np.linalg.norm(moved[thumb] - mesh.vertices[thumb], axis=1).min() > 0.5  # the thumb went with the hand
    # and stayed on it: where the arm's rigid motion puts it, to a millimetre
    assert _rigid_fit_residual(mesh.vertices[arm], moved[arm], mesh.vertices[thumb], moved[thumb]) < 1e-3


def test_a_bolt_on_the_head_stays_when_the_hand_beside_it_swings_away():
    """The bolt lies nearer the hand's bone than the head's: only touch tells that it is the head's."""
    bolt = trimesh.creation.icosphere(subdivisions=2, radius=0.012)
    bolt.apply_translation([0.1 + 0.011, 1.6, 0.0])  # 1 mm into the head's side that faces the hand
    mesh = mesh_from_trimesh(trimesh.util.concatenate(_head_and_arm() + [bolt]), "head_bolt_arm")
    pieces = vertex_pieces(mesh.vertices, mesh.faces)
    small = pieces == np.bincount(pieces).argmin()
    centre = mesh.vertices[small].mean(axis=0)
    assert np.linalg.norm(centre - BIND[4]) < 0.5 * np.linalg.norm(centre - BIND[1])  # nearer the hand
    graph = kinetre.build_graph(mesh, nodes=128)
    rig = kinetre.attach(graph, _pose(BIND[4]), node_bones=True, rigid=True, mesh=mesh)
    moved = kinetre.skin(mesh, graph, rig.solve(_pose(BIND[3] + 0.62 * np.array([0.7, -0.714, 0.0]))))
    arm = pieces == pieces[np.argmin(np.linalg.norm(mesh.vertices - BIND[3], axis=1))]
    assert np.linalg.norm(moved[arm] - mesh.vertices[arm], axis=1).max() > 0.5  # the arm swung
    assert np.linalg.norm(moved[small] - mesh.vertices[small], axis=1).max() < 1e-3  # the bolt stayed


LEGS = SkeletonModel("legs", ("body", "hip_a", "knee_a", "hip_b", "knee_b"), (-1, 0, 1, 0, 3))
LEG_A, LEG_B = 1, 3  # rows of LEGS.bones: hip_a -> knee_a, hip_b -> knee_b


def _capsule(a, b, radius) -> trimesh.Trimesh:
    a, b = np.asarray(a, float), np.asarray(b, float)
    c = trimesh.creation.capsule(height=float(np.linalg.norm(b - a)), radius=radius, count=[16, 16])
    c.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], (b - a) / np.linalg.norm(b - a)))
    c.apply_translation(0.5 * (a + b))
    return c


def test_a_neighbouring_leg_swung_across_a_thin_leg_does_not_carry_it():
    """Two thin legs side by side, one swung 35 degrees across the other in the bind pose (a many-legged walk's
    first frame): the swung bone runs a short chord through the other's capsule, three of its nine test
    points, and must not carry it; each leg is its own bone's."""
    hip_a, hip_b = np.array([0.0, 0.3, 0.0]), np.array([0.0, 0.3, 0.08])
    knee_a = hip_a + 0.27 * np.array([1.0, 0.0, 0.0])
    swung = np.array([np.cos(0.6), 0.0, -np.sin(0.6)])
    knee_b = hip_b + 0.27 * swung
    pos = np.array([[-0.1, 0.3, 0.04], hip_a, knee_a, hip_b, knee_b])
    leg_a, leg_b = _capsule(hip_a, knee_a, 0.025), _capsule(hip_b, knee_b, 0.025)
    mesh = mesh_from_trimesh(trimesh.util.concatenate([leg_a, leg_b]), "crossed_legs")
    graph = kinetre.build_graph(mesh, nodes=96)
    allowed = piece_bones(graph, Skeleton(LEGS, pos, np.ones(5, bool)), np.ones(5, bool), mesh)
    pieces = vertex_pieces(mesh.vertices, mesh.faces)
    a = int(pieces[np.argmin(np.linalg.norm(mesh.vertices - knee_a, axis=1))])
    b = int(pieces[np.argmin(np.linalg.norm(mesh.vertices - knee_b, axis=1))])
    assert a != b
    t = np.linspace(0.0, 0.27, 271)[:, None]
    chord = np.hypot((hip_b + t * swung)[:, 1] - 0.3, (hip_b + t * swung)[:, 2]) < 0.025  # within leg a
    assert 0.2 < chord.mean() < 0.4  # the swung bone crosses leg a for about a third of its length
    assert allowed[a, LEG_A] and not allowed[a, LEG_B]
    assert allowed[b, LEG_B] and not allowed[b, LEG_A]
