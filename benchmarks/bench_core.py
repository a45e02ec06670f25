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
from kinetre.deform.local_global import LocalGlobalSettings  # noqa: E402
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


# one record per design: the default (half-cycle PCG), variants of it, the other preconditioners, and the
# exact reference
DESIGNS = {
    "pcg_half_cycle": SolverSettings(),
    "pcg_half_cycle_gauss_newton_blocks": SolverSettings(curvature=False),
    "pcg_half_cycle_no_backtracking": SolverSettings(backtracks=0),
    "pcg_half_cycle_cg_tolerance_0.05": SolverSettings(cg_tolerance=0.05),
    "pcg_two_level": SolverSettings(preconditioner="two_level"),
    "pcg_two_level_gauss_newton_blocks": SolverSettings(preconditioner="two_level", curvature=False),
    "pcg_two_level_one_cg": SolverSettings(preconditioner="two_level", cg_iterations=1),
    "pcg_v_cycle": SolverSettings(preconditioner="v_cycle"),
    "pcg_additive": SolverSettings(preconditioner="additive"),
    "pcg_coordinate": SolverSettings(preconditioner="coordinate"),
    "pcg_block_jacobi": SolverSettings(preconditioner="block_jacobi"),
    # issue 9's alternative (`local_global.py`): by default one local/global iteration, then the PCG loop;
    # "alone" runs them until the gain test (or a stall) ends them
    "local_global": SolverSettings(method="local_global"),
    "local_global_two_then_pcg": SolverSettings(method="local_global",
                                                local_global=LocalGlobalSettings(then_gauss_newton=2)),
    "local_global_alone": SolverSettings(method="local_global", local_global=LocalGlobalSettings(then_gauss_newton=0)),
    "local_global_alone_tight": SolverSettings(method="local_global", local_global=LocalGlobalSettings(
        then_gauss_newton=0, gain_tolerance=1e-6, max_iterations=40)),
    "local_global_alone_no_anderson": SolverSettings(method="local_global", local_global=LocalGlobalSettings(
        then_gauss_newton=0, memory=0)),
    "local_global_alone_global_only": SolverSettings(method="local_global", local_global=LocalGlobalSettings(
        then_gauss_newton=0, local=False)),
    "exact_gn": SolverSettings(method="exact"),
    "exact_reuse_factor": SolverSettings(method="exact", reuse_factor=True),
}


def bench_solve(node_counts=(128, 256, 512), designs=tuple(DESIGNS)):
    # a body built around the clip's first frame, so the skeleton is inside it as after "possess"
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, len(take), 4)]  # 30 fps
    body = capsule_body(frames[0], radius=0.06)
    second = [f.transformed(translation=(0.03, 0.0, 0.02)) for f in frames[10:] + frames[:10]]
    for nodes in node_counts:
        graph = kinetre.build_graph(body, nodes=nodes)
        for skeletons in (1, 2):
            binds = [frames[0], second[0]][:skeletons]
            reference_energy = None
            for mode in ("exact_gn",) + tuple(d for d in designs if d != "exact_gn"):
                rig = kinetre.attach(graph, binds, settings=DESIGNS[mode])
                times, cpu, iters, facts, cgs, energies = [], [], [], [], [], []
                for i in range(1, len(frames)):
                    cur = [frames[i], second[i]][:skeletons]
                    c = time.thread_time()
                    t = time.perf_counter()
                    rig.solve(cur)
                    times.append(time.perf_counter() - t)
                    cpu.append(time.thread_time() - c)
                    rep = rig.last_report
                    iters.append(rep.iterations), facts.append(rep.factorisations), cgs.append(rep.cg_iterations)
                    energies.append(rep.energy)
                energies = np.array(energies)
                if mode == "exact_gn":
                    reference_energy = energies
                    if mode not in designs:
                        continue
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
                rel = energies / reference_energy - 1.0  # each run warm-starts from its own poses
                emit({"bench": "solve", "nodes": nodes, "graph_nodes": graph.node_count, "skeletons": skeletons,
                      "mode": mode, "constraints": rig.constraint_count, "frames": len(times),
                      "ms_per_frame_median": round(float(np.median(times)), 3),
                      "ms_per_frame_p95": round(float(np.percentile(times, 95)), 3),
                      # CPU time of the solving thread: on a shared machine, wall time minus waiting for a core
                      "cpu_ms_per_frame_median": round(float(np.median(cpu[5:])) * 1e3, 3),
                      "iterations_mean": round(float(it.mean()), 2),
                      "cg_iterations_mean": round(float(np.mean(cgs[5:])), 2),
                      "factorisations_mean": round(float(np.mean(facts[5:])), 2),
                      "ms_per_iter": round(float(ms_iter), 3),
                      "reference_ms_per_iter": round(float(np.median(ref)), 3),
                      "speedup_vs_reference_iter": round(float(np.median(ref) / np.median(times)), 1),
                      "speedup_per_iter": round(float(np.median(ref) / ms_iter), 1),
                      "energy_vs_exact_median": float(f"{np.median(rel):.2e}"),
                      "energy_vs_exact_p95": float(f"{np.percentile(rel, 95):.2e}"),
                      "backend": rig.solver.backend})


def bench_coordinate_solve(node_counts=(256, 512)):
    """The preconditioner's global part, (K_σ ⊗ I₃)⁻¹ r for x, y, z at once, three ways: the sparse
    float32 factor (the solver's), a dense Cholesky (LAPACK potrs) and a dense inverse (one GEMM)."""
    from scipy.linalg import lapack

    from kinetre.deform.krylov import _coordinate_solve
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 40, 4)]
    body = capsule_body(frames[0], radius=0.06)
    for nodes in node_counts:
        rig = kinetre.attach(kinetre.build_graph(body, nodes=nodes), frames[0])
        _, ok = rig.targets(frames[5])
        split = rig.solver.split
        k, fac, _ = split.for_active(ok.astype(float))
        dense = split._matrix(k[2] + split.shift_data).toarray()
        chol, _ = lapack.dpotrf(dense, lower=1)
        inverse = np.linalg.inv(dense)
        r = np.random.default_rng(0).standard_normal(3 * len(dense))
        out, work, rhs = np.empty_like(r), np.empty_like(r), r.reshape(-1, 3).copy()
        ways = {"sparse_factor": lambda: _coordinate_solve(*fac[:10], r, out, work),
                "dense_cholesky": lambda: lapack.dpotrs(chol, rhs, lower=1),
                "dense_inverse": lambda: inverse @ rhs}
        for name, fn in ways.items():
            fn()
            best = np.inf
            for _ in range(5):
                c = time.thread_time()
                for _ in range(50):
                    fn()
                best = min(best, (time.thread_time() - c) / 50)
            emit({"bench": "coordinate_solve", "nodes": nodes, "unknowns": len(dense), "way": name,
                  "factor_entries": int(len(fac[2]) + len(fac[6]) + len(dense)) if name == "sparse_factor" else
                  int(dense.size), "cpu_us": round(best * 1e6, 1)})


def skinning_case(mesh: kinetre.Mesh, count: int = 1_000_000):
    """`count` vertices (the mesh's, tiled) with its 256-node graph's indices and weights, and the node matrices
    of a random pose: (vertices, indices, weights, matrices, graph)."""
    graph = kinetre.build_graph(mesh, nodes=256)
    reps = int(np.ceil(count / len(mesh.vertices)))
    verts = np.concatenate([mesh.vertices + i for i in range(reps)])[:count]
    idx = np.concatenate([graph.vertex_nodes] * reps)[:count]
    w = np.concatenate([graph.vertex_weights] * reps)[:count]
    rng = np.random.default_rng(0)
    pose = kinetre.GraphPose(np.eye(3) + 0.1 * rng.standard_normal((graph.node_count, 3, 3)),
                             rng.standard_normal((graph.node_count, 3)))
    return verts, idx, w, pose.node_matrices(graph.nodes), graph


def bench_skin():
    """The 1M-vertex blend on this process's numba threads (one under `make bench`: the figure that counts),
    then a separate `"threads": 2` record from a child process allowed two (prange over the vertices)."""
    import numba
    from kinetre.deform.skinning import skin_vertices
    verts, idx, w, mats, _ = skinning_case(subdivided(kinetre.load_mesh(DATA / "meshes" / "armadillo.obj"), 2))
    skin_vertices(verts[:10], idx[:10], w[:10], mats)
    out = np.empty_like(verts)
    times, cpu = [], []
    for _ in range(10):
        t, c = time.perf_counter(), time.process_time()
        skin_vertices(verts, idx, w, mats, out=out)
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    # wall median and minimum, and the median CPU time of the process (every thread): on a shared machine
    # the wall figures include the time other programs hold the cores
    record = {"bench": "skin", "vertices": len(verts), "ms": round(float(np.median(times)) * 1e3, 2),
              "ms_min": round(min(times) * 1e3, 2), "cpu_ms": round(float(np.median(cpu)) * 1e3, 2)}
    if numba.config.NUMBA_NUM_THREADS > 1:
        record["threads"] = numba.config.NUMBA_NUM_THREADS
    emit(record)
    if numba.config.NUMBA_NUM_THREADS == 1:
        import os
        import subprocess
        env = dict(os.environ, NUMBA_NUM_THREADS="2", OMP_NUM_THREADS="1")
        subprocess.run([sys.executable, __file__, "skin"], env=env, check=True, timeout=600)


if __name__ == "__main__":
    which = sys.argv[1:] or ["build_graph", "solve", "coordinate_solve", "skin"]
    for name in which:
        if name.startswith("solve:"):  # e.g. solve:256 → one node count, every design
            bench_solve(node_counts=tuple(int(n) for n in name[6:].split(",")))
        else:
            globals()[f"bench_{name}"]()
