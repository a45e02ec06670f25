"""`kinetre animate MESH --motion MOTION -o OUT`: the library's `kinetre.animate` with the file reading and
writing, progress bars and summary around it."""
from __future__ import annotations

import argparse
import gc
import sys
import time

from ..stopwatch import Stopwatch
from .common import (EPILOG, SCAN_KEYWORDS, VIDEO_EXTS, UsageError, add_cleanup_options, add_scan_options, cleaned,
                     frame_range, load_motion, output_ext, prepare_mediapipe, scan_options, write_report)

ANIMATE_OUTPUTS = (".glb", ".gltf", ".fbx", ".bvh", ".mp4", ".webm", ".kinetre.jsonl")


def register(sub) -> None:
    """Add `kinetre animate` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("animate", help="drive a mesh with a motion file and write glTF, BVH, video or a take",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mesh", help="mesh file (.obj .ply .stl .off .glb .gltf, optionally .gz), or RGB-D frames "
                                "(a folder or .zip) to scan first")
    p.add_argument("--person", type=int, default=None, metavar="ID",
                   help="a camera take's person to follow, by id (default: the main person)")
    p.add_argument("--motion", required=True, action="append",
                   help="motion: .bvh, .kinetre.jsonl, a video, or a glTF animation (Fox.glb#Walk, Fox.glb#1); "
                        "repeat it with --map to join several sources")
    p.add_argument("--hand", action="append", choices=("left", "right"), default=None,
                   help="drive with a camera take's left or right hand instead of the body: its 21 landmarks "
                        "as a skeleton, the fingers as the mesh's legs (a hand puppet); with --map, repeat it "
                        "(--hand left --hand right) for one source per hand")
    p.add_argument("--as-held", dest="hang", action="store_false",
                   help="--hand: fit the hand as it is held (by default it is turned so its fingertips hang "
                        "below its palm)")
    p.add_argument("--map", default=None, metavar="JSON",
                   help="joint map: rename, drop and pair the joints of the --motion sources (docs/joint-maps.md)")
    p.add_argument("-o", "--output", required=True, help=f"output: {' '.join(ANIMATE_OUTPUTS)}")
    p.add_argument("--nodes", type=int, default=None,
                   help="graph nodes (default 256; a rig's own skeleton standing in the mesh: 24 per bone, "
                        "at most 1024)")
    p.add_argument("--seed", type=int, default=0, help="graph sampling seed (default 0)")
    p.add_argument("--subset", action="append", metavar="JOINTS",
                   help='joints that drive, e.g. "right arm" or "HipCenter,right arm" (repeatable)')
    p.add_argument("--bind-frame", type=int, default=0, help="frame used as the bind pose (default 0)")
    p.add_argument("--solver", choices=("pcg", "exact"), default=None,
                   help="per-frame solver (default: the library's, pcg): pcg or exact (the reference)")
    p.add_argument("--fit", nargs="?", const="mesh", default=None, choices=("mesh", "height", "length"),
                   help="--fit alone: resize the mesh to the skeleton instead of the motion to the mesh; "
                        "--fit height|length: size a non-human source to the mesh by that extent")
    p.add_argument("--yaw", type=float, default=None,
                   help="degrees about +Y the skeleton is turned (people: from the mesh front +Z; other "
                        "skeletons: added to the facing found from the shapes)")
    p.add_argument("--flip", action="store_true", help="turn the skeleton round (the fit took front for back)")
    p.add_argument("--up", default="auto", metavar="auto|y|z|x|-x|-y|-z",
                   help="the mesh's up axis: auto (default: glTF is +Y up; other files stand on the axis their shape "
                        "rests on best, +Y kept unless clearly worse), or the stored axis to turn up (y: as stored); "
                        "the output is written standing, +Y up")
    p.add_argument("--scale", type=float, default=None, help="BVH: metres per file unit (default: guessed)")
    p.add_argument("--own-skeleton", action="store_true",
                   help="BVH/glTF: drive the mesh by the file's own bones, not the Kinect-20 map (unmapped files "
                        "always do)")
    p.add_argument("--fps", type=float, default=None, help="output frame rate (default: the take's, at most 30)")
    p.add_argument("--frames", default=None, metavar="START:END", help="use only these frames of the take")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many output frames")
    p.add_argument("--no-skeleton", dest="skeleton", action="store_false", help="video: do not draw the skeleton")
    add_cleanup_options(p)
    p.add_argument("--no-cache", dest="cache", action="store_false",
                   help="load and preprocess the mesh afresh, neither reading nor keeping its cleaned mesh, "
                        "graph and weights in the per-user cache (kept by default, found again by the file's "
                        "content and the settings)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")
    p.add_argument("--progress", action="store_true",
                   help="progress as lines on stderr ('kinetre: progress: solving 12/120'), for a program running "
                        "this one (the Blender add-on)")
    p.add_argument("--exact-joints", action="store_true",
                   help="glTF/FBX: every joint gets a parent carrying its stretch, so players skin exactly as "
                        "Kinetre does (by default only when dropping it would show)")
    add_scan_options(p, segment="plane")
    p.set_defaults(func=cmd_animate)


def cmd_animate(args, stats: dict | None = None) -> int:
    """`kinetre animate`; `stats` (if given) receives the sizes and seconds per stage (for benchmarks)."""
    # What each stage builds (numba's loaded kernels and their typing tables, the mesh, the graph) lives to
    # the end, and the command makes almost no reference cycles (the same ~2,200 objects for 30 or 300
    # frames): the cyclic collector's passes would only re-walk live objects, 0.25 s of a 3 s run.
    # Reference counting still frees everything else as it goes.
    enabled = gc.isenabled()
    gc.disable()
    try:
        return _animate(args, stats)
    finally:
        if enabled:
            gc.enable()


def _animate(args, stats: dict | None) -> int:
    import numpy as np

    import kinetre
    from ..animation import UPS, AnimateSettings, animate
    from ..motion.source import resample

    out_ext = output_ext(args.output, ANIMATE_OUTPUTS)
    if out_ext == ".fbx":
        from ..blender.fbx import check_fbx
        check_fbx(args.output)  # before any work: FBX needs Blender
    frames = frame_range(args.frames)
    if args.nodes is not None and args.nodes < 2:
        raise UsageError(f"--nodes must be at least 2, got {args.nodes}")
    if args.up not in UPS:  # checked here, not by argparse: one line on stderr, before any file is read
        raise UsageError(f"--up must be one of {', '.join(UPS)}, got {args.up!r}")
    watch = Stopwatch(stats)
    stats, lap = watch.seconds, watch.lap
    t0 = time.perf_counter()

    say = (lambda *a: None) if args.quiet else print
    take, motion_label = _load_motions(args)  # small: fail fast
    scan_notes: tuple[str, ...] = ()
    kept = None  # the mesh file's kept preprocessing (`kinetre.preprocessed`)
    from ..scan.subject import is_frames
    if is_frames(args.mesh):  # RGB-D frames: scan (plane segmentation by default), then rig and animate
        from ..scan.subject import scan_subject
        mesh, scanned, scan_notes = scan_subject(args.mesh, progress=not args.quiet and sys.stderr.isatty(),
                                                 **scan_options(args))
        say(f"scanned {args.mesh}: {scanned.frames_used} frames used, {scanned.frames_rejected} rejected, "
            f"{scanned.seconds:.1f} s; {scanned.depth.line()}")
        for warning in scanned.warnings:
            print(f"kinetre: warning: {args.mesh}: {warning}", file=sys.stderr)
        for note in scan_notes:
            print(f"kinetre: note: {note}", file=sys.stderr)
    else:
        given = ["--segment"] * (args.segment != "plane") + [
            f"--{name.replace('_', '-')}" for name in ("before", *SCAN_KEYWORDS) if getattr(args, name) is not None]
        if given:
            raise UsageError(f"{', '.join(given)}: scan options, which apply when the input is RGB-D frames "
                             f"(a folder or .zip)")
        if args.cache:
            from ..preprocessed import MeshCache
            kept = MeshCache.of_file(args.mesh)
        mesh = kept.load_mesh() if kept is not None else kinetre.load_mesh(args.mesh)
    take = take.slice(frames.start or 0, frames.stop)
    fps = args.fps if args.fps is not None else min(take.fps, 30.0)
    take = resample(take, fps)
    if args.max_frames is not None:
        take = take.slice(0, max(1, args.max_frames))
    before = take
    if not args.hand and args.map is None:  # a hand or a joined map has no feet on a floor
        take = cleaned(take, args, say)
    elif args.contact:
        raise UsageError("--contact holds a body's feet: not with --hand or --map")
    if not -len(take) <= args.bind_frame < len(take):
        raise UsageError(f"--bind-frame {args.bind_frame} is outside the take's {len(take)} frames")
    if args.hand and not take.tracked[args.bind_frame].any():
        from ..motion.hands import first_seen
        first = first_seen(take)
        raise UsageError(f"{motion_label}: the hand is not seen in the bind frame {args.bind_frame}"
                         + (f"; it is first seen in frame {first}: try --bind-frame {first}" if first >= 0 else
                            " nor in any frame of --frames"))
    lap("load")
    say(f"mesh {args.mesh}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces")
    say(f"motion {motion_label}: {take.model.name}, {len(take.model.joints)} joints, {len(take)} frames "
        f"at {take.fps:g} fps")

    settings = AnimateSettings(nodes=args.nodes, seed=args.seed, subset=_subset(args.subset),
                               bind_frame=args.bind_frame, solver=args.solver, fit=args.fit, yaw=args.yaw,
                               flip=args.flip, solve=out_ext not in (".bvh", ".kinetre.jsonl"), up=args.up,
                               hang=args.hang)
    lines = args.progress and not args.quiet
    with _bar(3, "rigging", args.quiet, lines) as rigging, _bar(len(take), "solving", args.quiet, lines) as solving:
        rigging.unit = "step"
        result = animate(mesh, take, settings, on_frame=lambda i: solving.update(1),
                         on_step=lambda name: rigging.update(1), kept=kept)
    stats.update(result.seconds)
    watch.restart()
    placement, rig = result.placement, result.rig
    say(f"up: {result.upright.reason}")
    shape = result.shape_fit
    if shape is not None:
        say(f"fitted from the shapes: front by {shape.front}, turned {shape.turn:.0f} deg, size ratios "
            f"height {shape.ratios[0]:.3g} length {shape.ratios[1]:.3g}, {100 * shape.inside:.0f} % of the "
            f"bones inside the mesh")
    if placement.method == "in place":
        say(f"the motion's own skeleton ({len(result.take.model.joints)} joints) stands inside the mesh: "
            f"used where it stands")
    att = rig.attachments[0]
    joints = [att.bind.model.joints[j] for j in rig.attached_joints[0]]
    bind_height = att.bind.height
    say(f"attached {len(joints)} joint(s) ({', '.join(joints) or 'none'}), {int((att.bone >= 0).sum())} bone "
        f"samples, {len(rig.nodes_used)} of {rig.graph.node_count} nodes (mesh scaled by "
        f"{placement.mesh_scale:.4g} to the {bind_height:.2f} m skeleton)")
    for note in result.notes:
        print(f"kinetre: poor match: {note}", file=sys.stderr)

    out_take = result.take
    if out_ext in (".bvh", ".kinetre.jsonl"):
        _write_skeleton(args.output, out_ext, out_take)
    else:
        poses = list(result.poses)
        if out_ext in (".glb", ".gltf", ".fbx"):
            from ..blender.fbx import gltf_or_fbx
            from ..export.gltf import write_gltf
            with gltf_or_fbx(args.output, take.fps) as path:  # FBX: Blender converts the glTF
                write_gltf(path, result.mesh, result.graph, poses, take.fps,
                           stretch=True if args.exact_joints or out_ext == ".fbx" else None)
        else:
            from ..export.video import write_video
            skeletons = [[out_take.frame(i)] for i in range(len(out_take))] if args.skeleton else None
            with _bar(len(poses), "rendering", args.quiet, lines) as bar:
                write_video(args.output, result.mesh, result.graph, poses, take.fps, skeletons=skeletons,
                            on_frame=lambda i: bar.update(1))
        energy = np.array([p.energy for p in poses], dtype=float)
        solved = energy[np.isfinite(energy)]  # held frames (nothing tracked) have no energy
        say(f"solved {len(poses)} frames, median energy {np.median(solved) if solved.size else float('nan'):.3g}")
    if args.report:
        write_report(args.report, _report(args, before, take, result, out_ext))
        say(f"wrote {args.report}")
    lap("write")
    stats.update(vertices=len(mesh.vertices), nodes=rig.graph.node_count, frames=len(take),
                 total_s=time.perf_counter() - t0)
    stages = ", ".join(f"{k[:-2]} {v:.1f}" for k, v in stats.items() if k.endswith("_s") and k != "total_s")
    say(f"wrote {args.output} ({len(take)} frames at {take.fps:g} fps; {stats['total_s']:.1f} s: {stages})")
    return 0


def _report(args, before, take, result, out_ext: str) -> dict:
    """The quality of the driving take (as loaded and as cleaned) and of the output: the possessed mesh's
    lowest contact regions (the skeleton's contact joints when only a skeleton is written)."""
    from ..motion.quality import take_quality
    report = {"motion": args.motion, "output": args.output, "applied": take.applied,
              "take": take_quality(take).to_dict()}
    if take is not before:
        report["take_as_tracked"] = take_quality(before).to_dict()
    if result.poses:
        report["mesh_contacts"] = _mesh_contacts(result).to_dict()
    return report


def _mesh_contacts(result):
    """Quality of the possessed mesh's lowest regions: the connected pieces of the mesh within 3 % of its
    height of its lowest point as it stands (undeformed: the soles of a figure, a chair's leg ends), each
    followed by its centroid (in the solve frame's metres)."""
    import numpy as np
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from ..deform.skinning import skin_vertices
    from ..motion.quality import measure
    mesh, graph, out = result.mesh, result.graph, result.take
    rest = mesh.vertices
    height = float(np.ptp(rest[:, 1])) or 1.0
    is_low = rest[:, 1] <= rest[:, 1].min() + 0.03 * height
    # vertices split at UV seams are one point: join each to the first vertex at its place
    _, first, weld = np.unique(np.round(rest / (1e-6 * height)), axis=0, return_index=True, return_inverse=True)
    seams = np.column_stack([np.arange(len(rest)), first[weld.ravel()]])
    edges = np.concatenate([mesh.faces[:, [0, 1]], mesh.faces[:, [1, 2]], mesh.faces[:, [2, 0]], seams])
    edges = edges[is_low[edges].all(axis=1)]
    n = len(rest)
    _, label = connected_components(coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n)),
                                    directed=False)
    low = np.flatnonzero(is_low)
    pieces, counts = np.unique(label[low], return_counts=True)
    keep = pieces[counts >= max(3, 0.05 * len(low))]  # specks are not contact regions
    regions = [low[label[low] == k] for k in keep] or [low]
    names = tuple(f"mesh region {i + 1}" for i in range(len(regions)))
    idx = np.concatenate(regions)
    cut = np.cumsum([len(r) for r in regions])[:-1]
    centroids = np.empty((len(result.poses), len(regions), 3))
    for i, pose in enumerate(result.poses):
        v = skin_vertices(mesh.vertices[idx], graph.vertex_nodes[idx], graph.vertex_weights[idx],
                          pose.node_matrices(graph.nodes))
        centroids[i] = [part.mean(axis=0) for part in np.split(v, cut)]
    # the skeleton's joints give the body's height the thresholds scale with
    both = np.concatenate([out.positions, centroids], axis=1) / result.placement.output_scale
    j = out.positions.shape[1]
    return measure(both, out.fps, tuple(range(j, j + len(regions))), names)


def _load_motions(args):
    """The take `kinetre animate` drives with, and a label: one --motion (or one of its hands), or several
    sources (motions, or their hands) joined by --map."""
    motions = args.motion if isinstance(args.motion, list) else [args.motion]
    hands = args.hand or []
    if hands:
        from ..motion.hands import hand_take
    if any(m.lower().endswith(VIDEO_EXTS) for m in motions):
        prepare_mediapipe()
    if len(motions) > 1 and args.map is None:
        raise UsageError(f"{len(motions)} --motion given: a --map JSON says how they share the mesh "
                         f"(see docs/joint-maps.md)")
    if len(hands) > 1 and args.map is None:
        raise UsageError(f"{len(hands)} --hand given: a --map JSON says how the hands share the mesh "
                         f"(see docs/joint-maps.md)")
    if args.map is None:
        take = load_motion(motions[0], args.scale, as_kinect=not args.own_skeleton)
        who = "" if args.person is None else f"person {args.person}"
        if hands:
            take = hand_take(take, hands[0], args.person, motions[0])
            who = f"{hands[0]} hand" + (f" of {who}" if who else "")
        elif args.person is not None:
            take = take.person(args.person)
        return take, f"{motions[0]} ({who})" if who else motions[0]
    if args.person is not None:
        raise UsageError("--person picks one person; with --map each map entry takes a motion or a person")
    from ..motion.jointmap import join_takes, read_joint_map
    jmap = read_joint_map(args.map)
    takes = [load_motion(m, args.scale, as_kinect=not args.own_skeleton) for m in motions]
    if hands:  # one source per hand of each motion, in the order given
        takes = [hand_take(t, side, where=m) for m, t in zip(motions, takes) for side in hands]
    label = " + ".join(f"{m} ({side} hand)" for m in motions for side in hands) if hands else " + ".join(motions)
    return join_takes(takes, jmap), f"{label} via {args.map}"


def _write_skeleton(path: str, ext: str, take) -> None:
    if ext == ".bvh":
        from ..export.bvh import write_bvh
        write_bvh(path, take.frames(), take.fps)
    else:
        from ..motion.stream import write_stream
        write_stream(path, take)


def _subset(items: list[str] | None):
    if not items:
        return None
    names = [n.strip() for item in items for n in item.split(",") if n.strip()]
    return names[0] if len(names) == 1 else names


def _bar(total: int, desc: str, quiet: bool, lines: bool = False):
    # bars only on a terminal, so piped or captured stderr holds just the error line (and asked-for progress)
    if lines:
        return _LineBar(total, desc)
    if quiet or not sys.stderr.isatty():
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit="frame", file=sys.stderr, leave=False)


class _LineBar:
    """`--progress`: one line per step on stderr, for a program reading it."""

    def __init__(self, total: int, desc: str):
        self.total, self.desc, self.n, self.unit = total, desc, 0, "frame"

    def update(self, n: int = 1) -> None:
        self.n += n
        print(f"kinetre: progress: {self.desc} {self.n}/{self.total}", file=sys.stderr, flush=True)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass


class _NoBar:
    """What a disabled tqdm bar does (nothing), without importing tqdm and multiprocessing."""
    unit = "frame"

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass
