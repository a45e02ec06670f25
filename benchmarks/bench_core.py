"""Core engine figures: graph build, per-frame solve (vs the spsolve reference), CPU skinning.

Prints one JSON object per line. Run on one core: OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1.
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

import kinetre
from kinetre.deform.energy import EnergyWeights
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.motion.bvh import load_bvh

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference_solver import reference_iteration  # noqa: E402
from synthetic import capsule_body  # noqa: E402
from kinetre.deform.solver import SolverSettings  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"


def emit(record):
    print(json.dumps(record), flush=True)


def subdivided(mesh: kinetre.Mesh, times: int) -> kinetre.Mesh:
    v, f = mesh.vertices, mesh.faces
    for _ in range(times):
        v, f = trimesh.remesh.subdivide(v, f)
    return mesh_from_trimesh(trimesh.Trimesh(v, f, process=False), f"{mesh.source} x{times}")


def bench_build_graph():
    spot = kinetre.load_mesh(DATA / "meshes" / "spot.obj")
    arm = kinetre.load_mesh(DATA / "meshes" / "armadillo.obj")
    kinetre.build_graph(spot, nodes=128)  # JIT warm-up (cached after the first run)
    for mesh in (subdivided(spot, 1), kinetre.load_mesh(DATA / "meshes" / "elephant_loop3_large.ply.gz"),
                 subdivided(arm, 3)):
        for nodes in (128, 256):
            t = time.perf_counter()
            g = kinetre.build_graph(mesh, nodes=nodes)
            emit({"bench": "build_graph", "vertices": len(mesh.vertices), "nodes": g.node_count,
                  "seconds": round(time.perf_counter() - t, 3)})


def bench_solve():
    # a body built around the clip's first frame, so the skeleton is inside it as after "possess"
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, len(take), 4)]  # 30 fps
    body = capsule_body(frames[0], radius=0.06)
    second = [f.transformed(translation=(0.03, 0.0, 0.02)) for f in frames[10:] + frames[:10]]
    for nodes in (128, 256, 512):
        graph = kinetre.build_graph(body, nodes=nodes)
        for skeletons in (1, 2):
            for reuse in (False, True):
                binds = [frames[0], second[0]][:skeletons]
                rig = kinetre.attach(graph, binds, settings=SolverSettings(reuse_factor=reuse))
                times, iters, facts = [], [], []
                for i in range(1, len(frames)):
                    cur = [frames[i], second[i]][:skeletons]
                    t = time.perf_counter()
                    rig.solve(cur)
                    times.append(time.perf_counter() - t)
                    iters.append(rig.last_report.iterations)
                    facts.append(rig.last_report.factorisations)
                times = np.array(times[5:]) * 1e3  # after warm-up
                it = np.array(iters[5:])
                # the reference, one plain iteration from the same state on the same frame
                ref = []
                x = rig._x.copy()
                q, ok = rig.targets([frames[5], second[5]][:skeletons])
                for _ in range(3):
                    x, dt = reference_iteration(graph, rig.constraints, q, ok.astype(float), x, EnergyWeights())
                    ref.append(dt * 1e3)
                ms_iter = times.sum() / max(it.sum(), 1)
                emit({"bench": "solve", "nodes": graph.node_count, "skeletons": skeletons,
                      "mode": "reuse_factor" if reuse else "exact_gn",
                      "constraints": rig.constraint_count, "frames": len(times),
                      "ms_per_frame_median": round(float(np.median(times)), 3),
                      "ms_per_frame_p95": round(float(np.percentile(times, 95)), 3),
                      "iterations_mean": round(float(it.mean()), 2),
                      "factorisations_mean": round(float(np.mean(facts[5:])), 2),
                      "ms_per_iter": round(float(ms_iter), 3),
                      "reference_ms_per_iter": round(float(np.median(ref)), 3),
                      "speedup_per_iter": round(float(np.median(ref) / ms_iter), 1),
                      "backend": rig.solver.factor.backend})


def bench_skin():
    arm = kinetre.load_mesh(DATA / "meshes" / "armadillo.obj")
    big = subdivided(arm, 2)
    reps = int(np.ceil(1_000_000 / len(big.vertices)))
    verts = np.concatenate([big.vertices + i for i in range(reps)])[:1_000_000]
    graph = kinetre.build_graph(big, nodes=256)
    idx = np.concatenate([graph.vertex_nodes] * reps)[:1_000_000]
    w = np.concatenate([graph.vertex_weights] * reps)[:1_000_000]
    rng = np.random.default_rng(0)
    pose = kinetre.GraphPose(np.eye(3) + 0.1 * rng.standard_normal((graph.node_count, 3, 3)),
                             rng.standard_normal((graph.node_count, 3)))
    from kinetre.deform.skinning import skin_vertices
    mats = pose.node_matrices(graph.nodes)
    skin_vertices(verts[:10], idx[:10], w[:10], mats)
    times = []
    for _ in range(10):
        t = time.perf_counter()
        skin_vertices(verts, idx, w, mats)
        times.append(time.perf_counter() - t)
    emit({"bench": "skin", "vertices": len(verts), "ms": round(float(np.median(times)) * 1e3, 2)})


if __name__ == "__main__":
    which = sys.argv[1:] or ["build_graph", "solve", "skin"]
    for name in which:
        globals()[f"bench_{name}"]()
