"""Preprocessing and skinning figures: graph + weights of a 2.77M-vertex mesh, the same with the inside and
contact tests of a 66-piece mesh, CPU skinning of 1M vertices. `kinetre animate` end to end is in bench_animate.py.

Prints one JSON object per line. CPU seconds (time.process_time) are the figures to compare on a shared
machine; run on one core: OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1. Targets: graph + weights of a 2M-vertex
mesh ≤ 1.5 s, the 66-piece 100k-triangle case ≤ 0.5 s, skinning 1M vertices ≤ 15 ms.
"""
from __future__ import annotations

import dataclasses
import json
import sys
import time

import numpy as np

import kinetre
from bench_core import DATA, skinning_case, subdivided
from kinetre.deform.skinning import SkinTable, skin_vertices
from kinetre.graph.edges import bridge_edges, connect_components, knn_edges
from kinetre.graph.sampling import sample_orientation_aware
from kinetre.graph.weights import skinning_weights


def emit(record):
    print(json.dumps(record), flush=True)


def cpu(fn):
    c, t = time.process_time(), time.perf_counter()
    out = fn()
    return out, time.process_time() - c, time.perf_counter() - t


def fresh(mesh):
    """The same mesh without what it keeps once computed (its pieces): every timed build pays for them."""
    return dataclasses.replace(mesh)


def bench_graph(mesh):
    kinetre.build_graph(kinetre.load_mesh(DATA / "meshes" / "spot.obj"), nodes=64)  # load the cached kernels
    for nodes in (128, 256):
        g, total, wall = cpu(lambda: kinetre.build_graph(fresh(mesh), nodes=nodes))
        _, t_pieces, _ = cpu(lambda: fresh(mesh).pieces)
        (p, n, r), t_sample, _ = cpu(lambda: sample_orientation_aware(mesh.vertices, mesh.faces, mesh.normals,
                                                                        nodes=nodes))
        _, t_edges, _ = cpu(lambda: bridge_edges(len(p), connect_components(p, knn_edges(p, n, 4))[0]))
        _, t_weights, _ = cpu(lambda: skinning_weights(mesh.vertices, mesh.normals, p, n, r))
        emit({"bench": "graph_weights", "vertices": len(mesh.vertices), "nodes": g.node_count,
              "cpu_s": round(total, 3), "wall_s": round(wall, 3), "cpu_s_per_2M_vertices":
              round(total * 2e6 / len(mesh.vertices), 3), "sampling_cpu_s": round(t_sample, 3),
              "edges_cpu_s": round(t_edges, 3), "weights_cpu_s": round(t_weights, 3),
              "pieces_cpu_s": round(t_pieces, 3), "target_s_per_2M": 1.5})


def bench_skin(mesh):
    verts, idx, w, mats, graph = skinning_case(mesh)  # 1M vertices: the mesh's own, tiled
    out = np.empty_like(verts)
    table, out32 = SkinTable.prepare(verts, idx, w, graph.node_count), np.empty(verts.shape, np.float32)
    for label, call in (("new_array", lambda: skin_vertices(verts, idx, w, mats)),
                        ("out_buffer", lambda: skin_vertices(verts, idx, w, mats, out=out)),
                        ("float32_table", lambda: table.skin(mats, out32))):
        call()
        runs = [cpu(call)[1:] for _ in range(30)]
        c, t = np.array(runs).T * 1e3
        emit({"bench": "skin_1m", "vertices": len(verts), "nodes": graph.node_count, "output": label,
              "cpu_ms_median": round(float(np.median(c)), 2), "cpu_ms_min": round(float(c.min()), 2),
              "wall_ms_median": round(float(np.median(t)), 2), "target_ms": 15.0})


def many_pieces(pieces: int = 66, triangles: int = 100_000):
    """A robot of `pieces` separate parts and about `triangles` triangles: a capsule round every bone of the
    walk's first frame (overlapping its neighbours at the joints) and small spheres (bolts) sitting on them, no
    bone running through a bolt; and that skeleton frame."""
    import trimesh

    from kinetre.mesh.load import mesh_from_trimesh
    from kinetre.mesh.pieces import connected_pieces
    from kinetre.motion.bvh import load_bvh
    frame = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh").frame(0)
    height = float(np.ptp(frame.positions[:, 1]))
    bones = [(a, b) for a, b in frame.model.bones
             if np.linalg.norm(frame.positions[b] - frame.positions[a]) > 1e-3 * height]
    radius, bolt = 0.04 * height, 0.01 * height
    rng = np.random.default_rng(0)
    parts = []
    for a, b in bones:  # a capsule round every bone
        pa, pb = frame.positions[a], frame.positions[b]
        part = trimesh.creation.capsule(height=float(np.linalg.norm(pb - pa)), radius=radius, count=[32, 32])
        part.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], (pb - pa) / np.linalg.norm(pb - pa)))
        part.apply_translation(0.5 * (pa + pb))
        parts.append(part)
    # bolts on the capsules, at random points along them and round them, until there are `pieces` (capsules
    # whose ends meet weld into one piece)
    while connected_pieces((whole := trimesh.util.concatenate(parts)).vertices, whole.faces)[1] < pieces:
        a, b = bones[rng.integers(len(bones))]
        pa, pb = frame.positions[a], frame.positions[b]
        side = np.cross(pb - pa, rng.standard_normal(3))
        side /= np.linalg.norm(side)
        part = trimesh.creation.icosphere(subdivisions=3, radius=bolt)
        part.apply_translation(pa + rng.uniform(0.2, 0.8) * (pb - pa) + (radius + 0.8 * bolt) * side)
        parts.append(part)
    whole = trimesh.util.concatenate(parts)
    while len(whole.faces) * 4 <= triangles * 1.3:
        whole = whole.subdivide()
    return mesh_from_trimesh(whole, f"{pieces} pieces"), frame


def bench_pieces():
    """The graph with its weights of a mesh in many pieces, and which bones may carry each piece (the inside
    and contact tests of `piece_bones`), on a fresh mesh each run: least CPU seconds of three."""
    from kinetre.skeleton.piece_bones import piece_bones
    mesh, frame = many_pieces()
    kinetre.build_graph(kinetre.load_mesh(DATA / "meshes" / "spot.obj"), nodes=64)  # load the cached kernels
    piece_bones(kinetre.build_graph(mesh, nodes=256), frame, np.ones(len(frame.model.joints), bool), mesh)
    runs = []
    for _ in range(3):
        m = fresh(mesh)
        g, t_graph, _ = cpu(lambda: kinetre.build_graph(m, nodes=256))
        allowed, t_bones, _ = cpu(lambda: piece_bones(g, frame, np.ones(len(frame.model.joints), bool), m))
        runs.append((t_graph + t_bones, t_graph, t_bones))
    total, t_graph, t_bones = min(runs)
    emit({"bench": "pieces_prep", "pieces": mesh.pieces.count, "triangles": len(mesh.faces),
          "vertices": len(mesh.vertices), "nodes": g.node_count, "cpu_s": round(total, 3),
          "graph_weights_cpu_s": round(t_graph, 3), "piece_bones_cpu_s": round(t_bones, 3),
          "pieces_with_bones": int(allowed.any(axis=1).sum()) if allowed is not None else 0, "target_s": 0.5})


if __name__ == "__main__":
    which = sys.argv[1:] or ["skin", "graph", "pieces"]
    arm = kinetre.load_mesh(DATA / "meshes" / "armadillo.obj")
    if "skin" in which:
        bench_skin(subdivided(arm, 2))
    if "graph" in which:
        bench_graph(subdivided(arm, 3))  # 2.77M vertices
    if "pieces" in which:
        bench_pieces()
