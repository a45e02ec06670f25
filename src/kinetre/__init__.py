"""Kinetre: bring any mesh to life with your body.

    >>> import kinetre
    >>> mesh = kinetre.load_mesh("chair.obj")                     # doctest: +SKIP
    >>> graph = kinetre.build_graph(mesh, nodes=128)               # doctest: +SKIP
    >>> rig = kinetre.attach(graph, bind_skeleton)                 # doctest: +SKIP
    >>> pose = rig.solve(current_skeleton)                         # doctest: +SKIP
    >>> vertices = kinetre.skin(mesh, graph, pose)                 # doctest: +SKIP
"""
from .errors import (AttachError, BadGraphError, BadMeshError, BadMotionError, BadScanError,
                     BadSkeletonError, ExportError, KinetreError)
from .mesh.mesh import Mesh
from .mesh.load import load_mesh
from .graph.graph import DeformationGraph
from .graph.build import build_graph
from .deform.pose import GraphPose
from .deform.skinning import skin
from .skeleton.models import KINECT20, OPENNI17, Skeleton, SkeletonModel
from .skeleton.subsets import subset_mask, subset_names
from .skeleton.rig import Rig, attach

__all__ = [
    "AttachError", "BadGraphError", "BadMeshError", "BadMotionError", "BadScanError", "BadSkeletonError",
    "ExportError", "KinetreError", "Mesh", "load_mesh", "DeformationGraph", "build_graph", "GraphPose",
    "skin", "KINECT20", "OPENNI17", "Skeleton", "SkeletonModel", "subset_mask", "subset_names", "Rig",
    "attach",
]
