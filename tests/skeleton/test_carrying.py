"""A graph node takes the bone it sees from inside the mesh: a leg pushed up into the torso lies nearer to the
belly than the spine does, but behind the leg's own skin, so the belly follows the spine."""
import dataclasses

import numpy as np

import trimesh

from kinetre.graph.graph import DeformationGraph
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.skeleton.carrying import carrying_bones
from kinetre.skeleton.models import Skeleton, SkeletonModel

BODY = SkeletonModel("body", ("tail", "neck", "hip", "paw"), (-1, 0, 0, 2))
SPINE, LEG = 0, 2  # rows of BODY.bones: tail -> neck, hip -> paw
BIND = np.array([[-0.8, 0.9, 0.0], [0.8, 0.9, 0.0], [0.0, 0.3, 0.0], [0.0, -0.9, 0.0]])


def _torso_and_leg():
    torso = trimesh.creation.box(bounds=[[-1.0, 0.0, -1.0], [1.0, 1.0, 1.0]])
    leg = trimesh.creation.box(bounds=[[-0.2, -1.0, -0.2], [0.2, 0.6, 0.2]])  # pushed up into the torso
    return mesh_from_trimesh(trimesh.util.concatenate([torso, leg]))


def _graph(nodes, normals):
    return DeformationGraph(nodes=np.asarray(nodes, float), normals=np.asarray(normals, float),
                            edges=np.zeros((0, 2), np.int32), bridges=np.zeros(0, bool), radius=0.1,
                            vertex_nodes=np.empty((0, 4), np.int32), vertex_weights=np.empty((0, 4), np.float32))


def test_the_belly_follows_the_spine_not_the_leg_inside_the_torso():
    skeleton = Skeleton(BODY, BIND, np.ones(4, bool))
    belly = np.array([0.5, 0.0, 0.5])
    assert np.linalg.norm(belly - BIND[2]) < np.linalg.norm(belly - [0.5, 0.9, 0.0])  # the leg is nearer
    graph = _graph([belly, [0.0, -0.6, 0.2]], [[0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
    got = carrying_bones(graph, skeleton, np.ones(4, bool), _torso_and_leg())
    assert got.tolist() == [SPINE, LEG]  # the leg's own skin below the torso keeps its bone


def test_no_bone_may_carry_a_node_no_bone_is_allowed_for():
    skeleton = Skeleton(BODY, BIND, np.ones(4, bool))
    graph = _graph([[0.5, 0.0, 0.5]], [[0.0, -1.0, 0.0]])
    got = carrying_bones(graph, skeleton, np.ones(4, bool), _torso_and_leg(), np.zeros((1, 3), bool))
    assert got.tolist() == [-1]


def test_a_buried_node_keeps_a_bone_near_it_whatever_its_far_neighbours_hold():
    """A node whose skin is folded into its own part cannot tell its bone from where it is and takes its graph
    neighbours' bone, but only a bone near it: a coarse graph's edge to the far end of the spine does not make
    the spine carry the paw."""
    skeleton = Skeleton(BODY, BIND, np.ones(4, bool))
    paw = [0.0, -0.85, 0.15]  # its skin, just inside it along the normal, lies inside the leg: buried
    spine = [[-0.8, 0.95, 0.5], [-0.7, 0.95, -0.5]]  # the torso's skin over the spine's far end: seen clearly
    graph = _graph([paw, *spine], [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    graph = dataclasses.replace(graph, edges=np.array([[0, 1], [0, 2]], np.int32), bridges=np.zeros(2, bool))
    got = carrying_bones(graph, skeleton, np.ones(4, bool), _torso_and_leg())
    assert got.tolist() == [LEG, SPINE, SPINE]
