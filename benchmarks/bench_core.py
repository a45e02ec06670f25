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


BUILD_GRAPH_MESHES = {
    "spot": lambda: subdivided(kinetre.load_mesh(DATA / "meshes" / "spot.obj"), 1),
    "elephant": lambda: kinetre.load_mesh(DATA / "meshes" / "elephant_loop3_large.ply.gz"),
    "armadillo": lambda: subdivided(kinetre.load_mesh(DATA / "meshes" / "armadillo.obj"), 3),  # 2.77M vertices
}


def bench_build_graph(meshes=tuple(BUILD_GRAPH_MESHES), node_counts=(128, 256)):
    """Graph + skinning weights (`build_graph`), wall and process CPU seconds, and the CPU seconds scaled
    to 2M vertices (the cost should grow no faster than the vertex count)."""
    spot = kinetre.load_mesh(DATA / "meshes" / "spot.obj")
    kinetre.build_graph(spot, nodes=128)  # JIT warm-up (cached after the first run)
    for name in meshes:
        mesh = BUILD_GRAPH_MESHES[name]()
        for nodes in node_counts:
            t, c = time.perf_counter(), time.process_time()
            g = kinetre.build_graph(mesh, nodes=nodes)
            cpu = time.process_time() - c
            emit({"bench": "build_graph", "mesh": name, "vertices": len(mesh.vertices), "nodes": g.node_count,
                  "seconds": round(time.perf_counter() - t, 3), "cpu_s": round(cpu, 3),
                  "cpu_s_per_2M_vertices": round(cpu * 2e6 / len(mesh.vertices), 3)})


# one record per design worth an option: the default (adaptive: half cycle, two-level, coarse space), its parts,
# and the exact reference.
DESIGNS = {
    "pcg_adaptive": SolverSettings(),
    # the same preconditioners, a frame ends only on a step that gained < 1e-3 of E
    "pcg_adaptive_decrease": SolverSettings(remaining_tolerance=0.0),
    "pcg_adaptive_no_coarse": SolverSettings(coarse_regions=0),
    "pcg_half_cycle": SolverSettings(preconditioner="half_cycle", coarse_regions=0),
    "pcg_half_cycle_gauss_newton_blocks": SolverSettings(preconditioner="half_cycle", coarse_regions=0,
                                                         curvature=False),
    "pcg_two_level": SolverSettings(preconditioner="two_level", coarse_regions=0),
    "exact_gn": SolverSettings(method="exact"),
}
# what a solve carries over to the next frame, restored between the timed runs of one frame
_SOLVER_STATE = ("_lam", "_lam_exact", "_last_energy", "_jump_left", "_active_key", "_linear_data", "_cg_per_step",
                 "_coarse_on", "_contraction")


def timed_solve(rig, frame, repeats):
    """(least thread CPU seconds, least wall seconds) of `repeats` solves of `frame`, each from the same state
    (the warm start, the damping and the factor cache as before the first): the same warm-started sequence
    is replayed, the least time is the one least disturbed by the machine's other work."""
    x, before = rig._x.copy(), rig._x_before
    state = {k: getattr(rig.solver, k) for k in _SOLVER_STATE if hasattr(rig.solver, k)}
    split = rig.solver.split
    cache = (split._cache.copy(), split.factorisations) if split is not None else None
    cpu = wall = np.inf
    for r in range(repeats):
        if r:
            rig._x, rig._x_before = x.copy(), before
            for k, v in state.items():
                setattr(rig.solver, k, v)
            if cache is not None:  # a tracked-set change pays its factorisation in every run
                split._cache, split.factorisations = cache[0].copy(), cache[1]
        c, t = time.thread_time(), time.perf_counter()
        rig.solve(frame)
        cpu, wall = min(cpu, time.thread_time() - c), min(wall, time.perf_counter() - t)
    return cpu, wall


def walk_frames():
    """The walk at 30 fps and a second skeleton 3 cm aside, a third of the clip later."""
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, len(take), 4)]
    return frames, [f.transformed(translation=(0.03, 0.0, 0.02)) for f in frames[10:] + frames[:10]]


def replay(graph, skeletons, designs, subset=None, repeats=3, warm_up=8):
    """Each design of `designs` (name → SolverSettings, the first the reference) solves the walk with its own
    warm starts. Per design a warm-up pass over the first `warm_up` frames on a rig of its own (compilation,
    caches, clock) before the timed pass; in the timed pass the designs take turns frame by frame, each frame
    solved `repeats` times from the same state (`timed_solve`; the exact designs once: they are the slow
    reference). Returns per design arrays of CPU seconds, wall seconds, energies, steps, CG iterations,
    factorisations and whether E fell at every accepted step, and the last rig of each design."""
    frames, second = walk_frames()
    binds = [frames[0], second[0]][:skeletons]
    rigs = {}
    for name, settings in designs.items():
        warm = kinetre.attach(graph, binds, subset=subset, settings=settings)
        for i in range(1, warm_up + 1):
            warm.solve([frames[i], second[i]][:skeletons])
        rigs[name] = kinetre.attach(graph, binds, subset=subset, settings=settings)
    out = {name: {k: [] for k in ("cpu", "wall", "energy", "steps", "cg", "factorisations", "monotone")}
           for name in designs}
    for i in range(1, len(frames)):
        cur = [frames[i], second[i]][:skeletons]
        for name, rig in rigs.items():
            cpu, wall = timed_solve(rig, cur, 1 if rig.solver.settings.method == "exact" else repeats)
            rep, o = rig.last_report, out[name]
            o["cpu"].append(cpu), o["wall"].append(wall), o["energy"].append(rep.energy)
            o["steps"].append(rep.iterations), o["cg"].append(rep.cg_iterations)
            o["factorisations"].append(rep.factorisations)
            o["monotone"].append(bool(np.all(np.diff(rep.energies) < 0)))
    return {name: {k: np.array(v) for k, v in o.items()} for name, o in out.items()}, rigs


def bench_solve(cases=((256, 1), (256, 2), (512, 1), (512, 2), (256, 1, "right arm")),
                designs=tuple(DESIGNS), skip=5, reference=True):
    """Per (nodes, skeletons[, subset]) case and design: CPU time of the solving thread per frame, least of 3
    runs of the same warm-started frame, designs interleaved frame by frame (`replay`); the median over
    the frames after the first `skip`. `ms_per_frame_median` is that CPU figure (wall time, its least of
    3 too, beside it), against one plain spsolve Gauss-Newton iteration (`reference_solver.py`) timed
    in the same run; energies against the exact design's, each warm-started from its own poses."""
    frames, second = walk_frames()
    # a body built around the clip's first frame, so the skeleton is inside it as after "possess"
    body = capsule_body(frames[0], radius=0.06)
    graphs = {}
    for nodes, skeletons, *subset in cases:
        subset = subset[0] if subset else None
        if nodes not in graphs:
            graphs[nodes] = kinetre.build_graph(body, nodes=nodes)
        graph = graphs[nodes]
        # the exact design is the energy reference, left out only when asked (`--quick`)
        exact = reference or "exact_gn" in designs
        names = ["exact_gn"] * exact + [d for d in designs if d != "exact_gn"]
        runs, rigs = replay(graph, skeletons, {n: DESIGNS[n] for n in names}, subset)
        # the reference, one plain iteration from the same state on the same frame (the spsolve: seconds at
        # 1,024 nodes, left out with the exact design)
        ref = None
        if exact:
            rig = rigs[names[0]]
            q, ok = rig.targets([frames[skip], second[skip]][:skeletons])
            x, ref = rig._x.copy(), []
            for _ in range(3):
                x, dt = reference_iteration(graph, rig.constraints, q, ok.astype(float), x, EnergyWeights())
                ref.append(dt * 1e3)
            ref = float(np.min(ref))
        for name in names:
            if name not in designs:
                continue
            run = runs[name]
            ms, wall = run["cpu"][skip:] * 1e3, run["wall"][skip:] * 1e3
            steps = run["steps"][skip:]
            rel = run["energy"] / runs["exact_gn"]["energy"] - 1.0 if exact else None
            emit({"bench": "solve", "nodes": nodes, "graph_nodes": graph.node_count, "skeletons": skeletons,
                  "subset": subset, "mode": name, "constraints": rigs[name].constraint_count,
                  "frames": len(ms), "timing": "thread CPU, least of 3 runs per frame, designs interleaved"
                  if rigs[name].solver.settings.method != "exact" else "thread CPU, one run per frame",
                  "ms_per_frame_median": round(float(np.median(ms)), 3),
                  "ms_per_frame_p95": round(float(np.percentile(ms, 95)), 3),
                  "cpu_ms_per_frame_median": round(float(np.median(ms)), 3),
                  "wall_ms_per_frame_median": round(float(np.median(wall)), 3),
                  "iterations_mean": round(float(steps.mean()), 2),
                  "cg_iterations_mean": round(float(run["cg"][skip:].mean()), 2),
                  "factorisations_mean": round(float(run["factorisations"][skip:].mean()), 2),
                  "ms_per_iter": round(float(ms.sum() / max(steps.sum(), 1)), 3),
                  **({"reference_ms_per_iter": round(ref, 3),
                      "speedup_vs_reference_iter": round(ref / float(np.median(ms)), 1),
                      "speedup_per_iter": round(ref * max(steps.sum(), 1) / float(ms.sum()), 1)} if exact else {}),
                  **({"energy_vs_exact_median": float(f"{np.median(rel):.2e}"),
                      "energy_vs_exact_p95": float(f"{np.percentile(rel, 95):.2e}"),
                      "energy_vs_exact_max": float(f"{rel.max():.2e}")} if exact else {}),
                  "energy_never_rose": bool(run["monotone"].all()),
                  "backend": rigs[name].solver.backend})


# the reference for same-start agreement: the exact solve run on until a step gains less than 1e-7 of E (the
# default exact stop, 1e-3, ends up to a few 1e-2 above the minimum on some frames: see bench_solve_agreement)
EXACT_TIGHT = SolverSettings(method="exact", relative_tolerance=1e-7, max_iterations=30)


def same_start_gaps(graph, skeletons, designs, subset=None, count=64):
    """Per design (name → SolverSettings), E / E_ref − 1 frame by frame when every design starts each frame
    from the same state: the tight exact reference's previous pose (and the pose before it, for the
    constant-velocity guess). Each design keeps its own damping and adaptive state. Unlike `replay`, where
    every design warm-starts from its own poses, the trajectories cannot drift apart: the gap is the frame's
    own stopping accuracy. Returns ({name: gaps}, {name: steps}) over the walk's first `count` frames."""
    frames, second = walk_frames()
    binds = [frames[0], second[0]][:skeletons]
    ref = kinetre.attach(graph, binds, subset=subset, settings=EXACT_TIGHT)
    rigs = {n: kinetre.attach(graph, binds, subset=subset, settings=s) for n, s in designs.items()}
    gaps, steps = {n: [] for n in designs}, {n: [] for n in designs}
    for i in range(1, min(count, len(frames))):
        cur = [frames[i], second[i]][:skeletons]
        x, before = ref._x.copy(), ref._x_before
        e_ref = ref.solve(cur).energy
        for name, rig in rigs.items():
            rig._x, rig._x_before = x.copy(), None if before is None else before.copy()
            rig.solve(cur)
            gaps[name].append(rig.last_report.energy / e_ref - 1.0)
            steps[name].append(rig.last_report.iterations)
    return {n: np.array(v) for n, v in gaps.items()}, {n: np.array(v) for n, v in steps.items()}


def bench_solve_agreement(cases=((256, 2), (256, 1, "right arm")), skip=5):
    """Energy agreement with the same start (`same_start_gaps`): the default, the
    "decrease" stop rule and the exact solve with its default stop, against `EXACT_TIGHT`; median, p95 and
    max of the relative gap over the frames after the first `skip`. Two cases by default: the tight
    reference costs up to 30 factorisations a frame (these two took 7 min at load 2.5; 512 nodes ~2× each)."""
    frames, _ = walk_frames()
    body = capsule_body(frames[0], radius=0.06)
    designs = {"pcg_adaptive": DESIGNS["pcg_adaptive"], "pcg_adaptive_decrease": DESIGNS["pcg_adaptive_decrease"],
               "exact_gn": DESIGNS["exact_gn"]}
    graphs = {}
    for nodes, skeletons, *subset in cases:
        subset = subset[0] if subset else None
        graph = graphs.setdefault(nodes, kinetre.build_graph(body, nodes=nodes))
        gaps, steps = same_start_gaps(graph, skeletons, designs, subset)
        for name, gap in gaps.items():
            gap = gap[skip:]
            emit({"bench": "solve_agreement", "nodes": nodes, "graph_nodes": graph.node_count,
                  "skeletons": skeletons, "subset": subset, "mode": name, "frames": len(gap),
                  "reference": "exact, relative_tolerance 1e-7, max_iterations 30, same start each frame",
                  "iterations_mean": round(float(steps[name][skip:].mean()), 2),
                  "gap_median": float(f"{np.median(gap):.2e}"), "gap_p95": float(f"{np.percentile(gap, 95):.2e}"),
                  "gap_max": float(f"{gap.max():.2e}"), "gap_min": float(f"{gap.min():.2e}")})


def bench_solve_tail(nodes=256, lag=7, repeats=3):
    """The hard stretches of a live studio scene: two skeletons each possessing one leg of the capsule body,
    the second `lag` frames ahead on the same walk, twice round the clip (the loop-arounds pull the legs
    apart, then together). Per design, the per-frame CPU time of the solving thread (least of 3 runs of the
    same warm-started frame, designs interleaved frame by frame): median, p99 and max over the frames, and
    the frames with the coarse space on. The default's tail should be no worse than without the coarse
    space (`GaussNewton._follow`)."""
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, len(take), 4)]
    graph = kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=nodes)
    seq = [[frames[k % len(frames)], frames[(k + lag) % len(frames)]] for k in range(2 * len(frames))]
    designs = {"pcg_adaptive": SolverSettings(), "pcg_adaptive_no_coarse": SolverSettings(coarse_regions=0)}
    rigs = {n: kinetre.attach(graph, seq[0], subset=["left leg", "right leg"], settings=s) for n, s in designs.items()}
    out = {n: ([], [], []) for n in designs}
    for cur in seq[1:]:
        for name, rig in rigs.items():
            out[name][2].append(bool(rig.solver._preconditioner()[1]))
            cpu, _ = timed_solve(rig, cur, repeats)
            out[name][0].append(cpu * 1e3)
            out[name][1].append(rig.last_report.energy)
    for name, (ms, energy, coarse) in out.items():
        ms = np.array(ms[1:])  # the first solve is the exact start
        rel = np.array(energy) / np.array(out["pcg_adaptive_no_coarse"][1]) - 1.0
        emit({"bench": "solve_tail", "nodes": nodes, "graph_nodes": graph.node_count, "skeletons": 2,
              "subset": "one leg each", "lag_frames": lag, "mode": name, "frames": len(ms),
              "timing": "thread CPU, least of 3 runs per frame, designs interleaved",
              "ms_per_frame_median": round(float(np.median(ms)), 3),
              "ms_per_frame_p99": round(float(np.percentile(ms, 99)), 3),
              "ms_per_frame_max": round(float(ms.max()), 3),
              "coarse_frames": int(np.sum(coarse)),
              "energy_vs_no_coarse_median": float(f"{np.median(rel):.2e}")})


def bench_coordinate_solve(node_counts=(256, 512)):
    """The preconditioner's global part, (K_σ ⊗ I₃)⁻¹ r for x, y, z at once, three ways: the sparse factor in
    4 × 4 node blocks (the solver's), a dense Cholesky (LAPACK potrs) and a dense inverse (one GEMM)."""
    from scipy.linalg import lapack

    from kinetre.deform.fast.preconditioner import coordinate_solve
    take = load_bvh(DATA / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 40, 4)]
    body = capsule_body(frames[0], radius=0.06)
    for nodes in node_counts:
        rig = kinetre.attach(kinetre.build_graph(body, nodes=nodes), frames[0])
        _, ok = rig.targets(frames[5])
        split = rig.solver.split
        _, fac, _ = split.for_active(ok.astype(float))
        dense = split._matrix(split.k_data(ok.astype(float)) + split.shift_data).toarray()
        chol, _ = lapack.dpotrf(dense, lower=1)
        inverse = np.linalg.inv(dense)
        r = np.random.default_rng(0).standard_normal(3 * len(dense))
        out, work, rhs = np.empty_like(r), np.empty_like(r), r.reshape(-1, 3).copy()
        ways = {"sparse_factor": lambda: coordinate_solve(fac, r, out, work),
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
                  "factor_entries": int(fac[2].size + fac[3].size) if name == "sparse_factor" else
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


def bench_skin(quick=False):
    """The 1M-vertex blend per frame on this process's numba threads (one under `make bench`: the figure that
    counts): `SkinTable.skin` (float32, what video frames use; the record without "path"), then the float64
    `skin_vertices` reference, 15 frames each; then a separate `"threads": 2` record from a child process
    allowed two (prange over chunks of vertices)."""
    import numba
    from kinetre.deform.skinning import SkinTable, skin_vertices
    # the armadillo twice subdivided, tiled to 1M vertices (with --quick the armadillo itself, tiled: the same
    # blend per vertex, its graph built in a tenth of the time)
    armadillo = kinetre.load_mesh(DATA / "meshes" / "armadillo.obj")
    verts, idx, w, mats, graph = skinning_case(subdivided(armadillo, 2) if not quick else armadillo)
    t = time.process_time()
    table = SkinTable.prepare(verts, idx, w, graph.node_count)
    prepare = time.process_time() - t
    out32, out64 = np.empty((len(verts), 3), np.float32), np.empty_like(verts)
    calls = {"float32": lambda: table.skin(mats, out32),
             "float64": lambda: skin_vertices(verts, idx, w, mats, out=out64)}
    for call in calls.values():
        call()  # compile or load
    error = float(np.abs(out32 - out64).max() / np.linalg.norm(np.ptp(verts, axis=0)))
    times, cpu = {k: [] for k in calls}, {k: [] for k in calls}
    for name, call in calls.items():
        for _ in range(15):
            t, c = time.perf_counter(), time.process_time()
            call()
            times[name].append(time.perf_counter() - t)
            cpu[name].append(time.process_time() - c)
    threads = {"threads": numba.config.NUMBA_NUM_THREADS} if numba.config.NUMBA_NUM_THREADS > 1 else {}
    for name in calls:
        # wall median and minimum, and the median CPU time of the process (every thread): on a shared machine
        # the wall figures include the time other programs hold the cores
        record = {"bench": "skin", "vertices": len(verts), "nodes": graph.node_count,
                  "ms": round(float(np.median(times[name])) * 1e3, 2), "ms_min": round(min(times[name]) * 1e3, 2),
                  "cpu_ms": round(float(np.median(cpu[name])) * 1e3, 2), **threads}
        if name == "float32":
            record.update({"prepare_cpu_ms": round(prepare * 1e3, 1), "max_error_of_bbox_diagonal": error,
                           "target_ms": 15.0})
        else:
            record["path"] = "float64_reference"
        emit(record)
    if numba.config.NUMBA_NUM_THREADS == 1 and not quick:
        import os
        import subprocess
        env = dict(os.environ, NUMBA_NUM_THREADS="2", OMP_NUM_THREADS="1")
        subprocess.run([sys.executable, __file__, "skin"], env=env, check=True, timeout=600)


if __name__ == "__main__":
    # names as arguments run only those; `build_graph:elephant` one mesh (at 256 nodes with --quick),
    # `solve:256,1024` those node counts; `--quick` (make bench-quick): two skeletons and the default design
    # only, no exact reference, no two-thread skinning child
    args = sys.argv[1:]
    quick = "--quick" in args
    which = [a for a in args if a != "--quick"] or ["build_graph", "solve", "solve_agreement", "solve_tail",
                                                      "coordinate_solve", "skin"]
    for name in which:
        if name.startswith("solve:"):  # e.g. solve:256 → one node count, one and two skeletons, every design
            counts = [int(n) for n in name[6:].split(",")]
            if quick:
                bench_solve(cases=tuple((n, 2) for n in counts), designs=("pcg_adaptive",), reference=False)
            else:
                bench_solve(cases=tuple((n, k) for n in counts for k in (1, 2)))
        elif name.startswith("build_graph:"):
            bench_build_graph(meshes=tuple(name[12:].split(",")), node_counts=(256,) if quick else (128, 256))
        elif name == "skin":
            bench_skin(quick=quick)
        elif name == "solve":
            bench_solve()
            # the 1,024-node scale case: the default design alone (an exact reference per frame would take minutes)
            bench_solve(cases=((1024, 2),), designs=("pcg_adaptive",), reference=False)
        else:
            globals()[f"bench_{name}"]()
