"""Kinetre: bring any mesh to life with your body.

    >>> import kinetre
    >>> mesh = kinetre.load_mesh("chair.obj")                     # doctest: +SKIP
    >>> graph = kinetre.build_graph(mesh, nodes=128)               # doctest: +SKIP
    >>> rig = kinetre.attach(graph, bind_skeleton)                 # doctest: +SKIP
    >>> pose = rig.solve(current_skeleton)                         # doctest: +SKIP
    >>> vertices = kinetre.skin(mesh, graph, pose)                 # doctest: +SKIP

The names below are imported on first use (`kinetre.lazy`): `import kinetre` itself loads no numba,
scipy or trimesh.
"""
from .errors import (AttachError, BadGraphError, BadMeshError, BadMotionError, BadScanError,
                     BadSkeletonError, ExportError, KinetreError)
from .lazy import lazy_exports

_EXPORTS = {
    "Mesh": ".mesh.mesh", "load_mesh": ".mesh.load", "DeformationGraph": ".graph.graph",
    "build_graph": ".graph.build", "GraphPose": ".deform.pose", "skin": ".deform.skinning",
    "KINECT20": ".skeleton.models", "OPENNI17": ".skeleton.models", "HAND21": ".skeleton.models", "Skeleton": ".skeleton.models",
    "SkeletonModel": ".skeleton.models", "subset_mask": ".skeleton.subsets", "subset_names": ".skeleton.subsets",
    "Rig": ".skeleton.rig", "attach": ".skeleton.rig", "load_take": ".motion.source",
    "hand_take": ".motion.hands", "animate": ".animation", "AnimateSettings": ".animation",
    "Animation": ".animation",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = [
    "AttachError", "BadGraphError", "BadMeshError", "BadMotionError", "BadScanError", "BadSkeletonError",
    "ExportError", "KinetreError", "Mesh", "load_mesh", "DeformationGraph", "build_graph", "GraphPose",
    "skin", "KINECT20", "OPENNI17", "HAND21", "Skeleton", "SkeletonModel", "subset_mask", "subset_names", "Rig",
    "attach", "load_take", "hand_take", "animate", "AnimateSettings", "Animation",
]
