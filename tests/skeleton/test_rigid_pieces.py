"""A mesh in two pieces, one per bone: skinning stays on a vertex's own piece and the moving piece stays rigid."""
import numpy as np

import trimesh

import kinetre
from kinetre.graph.pieces import vertex_pieces
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.skeleton.models import Skeleton, SkeletonModel

ARM = SkeletonModel("arm", ("shoulder", "elbow", "wrist"), (-1, 0, 1))
BIND = np.array([[0.0, 1.0, 0.0], [0.6, 1.0, 0.0], [1.2, 1.0, 0.0]])


def _bent(degrees: float) -> Skeleton:
    a = np.radians(degrees)
    pos = BIND.copy()
    pos[2] = pos[1] + 0.6 * np.array([np.cos(a), np.sin(a), 0.0])
    return Skeleton(ARM, pos, np.ones(3, bool))


def _two_capsules() -> kinetre.Mesh:
    """An upper arm and a forearm as two separate capsules along +X, 4 cm apart at the elbow."""
    parts = []
    for start, stop in ((0.0, 0.56), (0.64, 1.2)):
        cap = trimesh.creation.capsule(height=stop - start - 0.1, radius=0.05, count=[12, 12])
        cap.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
        cap.apply_translation([0.5 * (start + stop), 1.0, 0.0])
        parts.append(cap)
    return mesh_from_trimesh(trimesh.util.concatenate(parts), "arm")


def _procrustes_residual(a: np.ndarray, b: np.ndarray) -> float:
    """RMS distance of b from the best rigid motion of a."""
    ca, cb = a - a.mean(axis=0), b - b.mean(axis=0)
    u, _, vt = np.linalg.svd(ca.T @ cb)
    d = np.sign(np.linalg.det(u @ vt))
    r = u @ np.diag([1.0, 1.0, d]) @ vt
    return float(np.sqrt(((ca @ r - cb) ** 2).sum(axis=1).mean()))


def test_two_piece_arm_keeps_the_forearm_rigid():
    mesh = _two_capsules()
    pieces = vertex_pieces(mesh.vertices, mesh.faces)
    assert len(np.unique(pieces)) == 2
    graph = kinetre.build_graph(mesh, nodes=64)
    # skinning stays on each vertex's piece
    used = graph.vertex_weights > 0
    assert (graph.pieces[graph.vertex_nodes][used] == np.repeat(pieces[:, None], 4, axis=1)[used]).all()
    rig = kinetre.attach(graph, _bent(0.0), rigid=True)
    assert len(rig.rigid_pieces) == 2  # each capsule's samples come from its own bone
    moved = kinetre.skin(mesh, graph, rig.solve(_bent(80.0)))
    fore = pieces == pieces[np.argmax(mesh.vertices[:, 0])]
    travel = np.linalg.norm(moved[fore] - mesh.vertices[fore], axis=1).mean()
    assert travel > 0.3  # the forearm swung up
    assert _procrustes_residual(mesh.vertices[fore], moved[fore]) < 1e-6
    # and it went where the bone went: the wrist end's vertices sit by the bent wrist
    tip = mesh.vertices[:, 0] > 1.15
    assert np.linalg.norm(moved[tip].mean(axis=0) - _bent(80.0).positions[2]) < 0.05
    assert np.abs(moved[~fore] - mesh.vertices[~fore]).max() < 1e-6  # the upper arm did not move
