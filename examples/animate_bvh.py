"""Animate a mesh with a BVH clip, step by step, and save it as a rigged glTF (what `kinetre animate` does).

    python examples/animate_bvh.py [MESH] [BVH] [OUT.glb]

Defaults: Spot the cow and the CMU walk bundled with kinetre, 30 frames, written to spot_walk.glb in the temp folder.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import kinetre
from kinetre.export.gltf import write_gltf
from kinetre.motion.bvh import load_bvh
from kinetre.motion.fit import fit_take
from kinetre.motion.source import resample

DATA = Path(kinetre.__file__).resolve().parent / "data"
mesh_path = sys.argv[1] if len(sys.argv) > 1 else DATA / "spot.obj"
bvh_path = sys.argv[2] if len(sys.argv) > 2 else DATA / "cmu_12_01_walk.bvh"
out_path = sys.argv[3] if len(sys.argv) > 3 else Path(tempfile.gettempdir()) / "spot_walk.glb"

mesh = kinetre.load_mesh(mesh_path)
take = resample(load_bvh(bvh_path), 30.0).slice(0, 30)        # Kinect-20 joints, metres, +Y up, 30 fps
print(f"{take.model.name} take: {len(take)} frames, skeleton {take.frame(0).height:.2f} m tall")

graph = kinetre.build_graph(mesh, nodes=96, seed=0)
placement = fit_take(take, mesh)                               # face +Z, centre, ground, scale the mesh to metres
placed = placement.take(take)
rig = kinetre.attach(placement.graph(graph), placed.frame(0))  # frame 0 is the bind pose
print(f"attached {rig.constraint_count} constraints on {len(rig.nodes_used)} of {graph.node_count} nodes")

poses = [placement.output_pose(rig.solve(placed.frame(i))) for i in range(len(placed))]
moved = [np.abs(kinetre.skin(mesh, graph, p) - mesh.vertices).max() for p in poses]
print(f"largest vertex displacement: {max(moved):.3f} (mesh units; bbox diagonal {mesh.diagonal:.3f})")
write_gltf(out_path, mesh, graph, poses, take.fps)
print(f"wrote {out_path}")
