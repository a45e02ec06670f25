"""Preprocessing and skinning figures: graph + weights of a 2.77M-vertex mesh, CPU skinning of 1M
vertices. `kinetre animate` end to end is in bench_animate.py.

Prints one JSON object per line. CPU seconds (time.process_time) are the figures to compare on a shared
machine; run on one core: OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1. Targets: graph + weights of a 2M-vertex
mesh ≤ 1.5 s, skinning 1M vertices ≤ 15 ms.
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


if __name__ == "__main__":
    which = sys.argv[1:] or ["skin", "graph"]
    arm = kinetre.load_mesh(DATA / "meshes" / "armadillo.obj")
    if "skin" in which:
        bench_skin(subdivided(arm, 2))
    if "graph" in which:
        bench_graph(subdivided(arm, 3))  # 2.77M vertices
