"""The `kinetre` command: thin wrappers over the API. Bad input -> one line on stderr and exit status 2."""
from __future__ import annotations

import argparse
import gc
import os
import sys
import time
from pathlib import Path

from .cli_common import UsageError
from .cli_common import frame_range as _frames
from .cli_common import load_motion as _load_motion
from .cli_common import output_ext as _ext
from .cli_common import quiet_mediapipe as _quiet_mediapipe
from .errors import KinetreError

EPILOG = """examples:
  kinetre animate chair.obj --motion walk.bvh -o chair_walk.glb
  kinetre animate lamp.obj --motion walk.bvh --subset "HipCenter,right arm" -o lamp.mp4
  kinetre animate spot.obj --motion take.kinetre.jsonl --fit --yaw 90 -o spot.glb
  kinetre animate horse.ply --motion Fox.glb#Walk -o horse.glb
  kinetre animate horse.ply --motion a.bvh --motion b.bvh --map two-people.json -o horse.glb
  kinetre animate frames/ --motion walk.bvh -o scan_walk.glb
  kinetre info Fox.glb
  kinetre capture --video clip.mp4 -o take.kinetre.jsonl
  kinetre capture --camera 0 --seconds 10 -o take.kinetre.jsonl
  kinetre record walk.bvh -o walk.kinetre.jsonl
  kinetre info walk.bvh
  kinetre graph spot.obj --nodes 128 -o spot_graph.ply
  kinetre studio spot.obj --port 8000
  kinetre scene horse.obj --nats nats://HOST:4222 --room stage --token SECRET
  kinetre avatar CesiumMan.glb --motion walk.bvh -o cesium_walk.glb
"""

MESH_EXTS = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
VIDEO_EXTS = (".mp4", ".mov", ".avi", ".mkv", ".webm")
ANIMATE_OUTPUTS = (".glb", ".gltf", ".bvh", ".mp4", ".webm", ".kinetre.jsonl")


def _subset(items: list[str] | None):
    if not items:
        return None
    names = [n.strip() for item in items for n in item.split(",") if n.strip()]
    return names[0] if len(names) == 1 else names


def _bar(total: int, desc: str, quiet: bool):
    # bars only on a terminal, so piped or captured stderr holds just the error line
    if quiet or not sys.stderr.isatty():
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit="frame", file=sys.stderr, leave=False)


class _NoBar:
    """What a disabled tqdm bar does (nothing), without importing tqdm and multiprocessing (~20 ms)."""
    unit = "frame"

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass


# ---- animate ---------------------------------------------------------------------------------------

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
    from .animation import AnimateSettings, animate
    from .motion.source import resample

    out_ext = _ext(args.output, ANIMATE_OUTPUTS)
    frames = _frames(args.frames)
    if args.nodes < 2:
        raise UsageError(f"--nodes must be at least 2, got {args.nodes}")
    stats = {} if stats is None else stats
    t0 = clock = time.perf_counter()
    cpu_clock = time.process_time()

    def lap(stage):
        nonlocal clock, cpu_clock
        now, cpu_now = time.perf_counter(), time.process_time()
        stats[f"{stage}_s"] = now - clock
        stats[f"{stage}_cpu"] = cpu_now - cpu_clock  # CPU seconds: what the stage costs on a shared machine
        clock, cpu_clock = now, cpu_now

    say = (lambda *a: None) if args.quiet else print
    take, motion_label = _load_motions(args)  # small: fail fast
    scan_notes: tuple[str, ...] = ()
    from .scan.subject import is_frames
    if is_frames(args.mesh):  # RGB-D frames: scan (plane segmentation by default), then rig and animate
        from .scan.subject import scan_subject
        mesh, scanned, scan_notes = scan_subject(args.mesh, None if args.segment == "none" else args.segment,
                                                 args.before, progress=not args.quiet and sys.stderr.isatty())
        say(f"scanned {args.mesh}: {scanned.frames_used} frames used, {scanned.frames_rejected} rejected, "
            f"{scanned.seconds:.1f} s")
        for note in scan_notes:
            print(f"kinetre: note: {note}", file=sys.stderr)
    else:
        if args.before is not None or args.segment != "plane":
            raise UsageError("--segment and --before apply when the input is RGB-D frames (a folder or .zip)")
        mesh = kinetre.load_mesh(args.mesh)
    take = take.slice(frames.start or 0, frames.stop)
    fps = args.fps if args.fps is not None else min(take.fps, 30.0)
    take = resample(take, fps)
    if args.max_frames is not None:
        take = take.slice(0, max(1, args.max_frames))
    if not -len(take) <= args.bind_frame < len(take):
        raise UsageError(f"--bind-frame {args.bind_frame} is outside the take's {len(take)} frames")
    lap("load")
    say(f"mesh {args.mesh}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces")
    say(f"motion {motion_label}: {take.model.name}, {len(take.model.joints)} joints, {len(take)} frames "
        f"at {take.fps:g} fps")

    settings = AnimateSettings(nodes=args.nodes, seed=args.seed, subset=_subset(args.subset),
                               bind_frame=args.bind_frame, solver=args.solver, fit=args.fit, yaw=args.yaw,
                               flip=args.flip, solve=out_ext not in (".bvh", ".kinetre.jsonl"))
    with _bar(3, "rigging", args.quiet) as rigging, _bar(len(take), "solving", args.quiet) as solving:
        rigging.unit = "step"
        result = animate(mesh, take, settings, on_frame=lambda i: solving.update(1),
                         on_step=lambda name: rigging.update(1))
    stats.update(result.seconds)
    clock, cpu_clock = time.perf_counter(), time.process_time()
    placement, rig = result.placement, result.rig
    shape = result.shape_fit
    if shape is not None:
        say(f"fitted from the shapes: front by {shape.front}, turned {shape.turn:.0f} deg, size ratios "
            f"height {shape.ratios[0]:.3g} length {shape.ratios[1]:.3g}, {100 * shape.inside:.0f} % of the "
            f"bones inside the mesh")
    att = rig.attachments[0]
    joints = [take.model.joints[j] for j in rig.attached_joints[0]]
    bind_height = placement.take(take).frame(args.bind_frame).height
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
        if out_ext in (".glb", ".gltf"):
            from .export.gltf import write_gltf
            write_gltf(args.output, result.mesh, result.graph, poses, take.fps)
        else:
            from .export.video import write_video
            skeletons = [[out_take.frame(i)] for i in range(len(out_take))] if args.skeleton else None
            with _bar(len(poses), "rendering", args.quiet) as bar:
                write_video(args.output, result.mesh, result.graph, poses, take.fps, skeletons=skeletons,
                            on_frame=lambda i: bar.update(1))
        energy = np.array([p.energy for p in poses], dtype=float)
        solved = energy[np.isfinite(energy)]  # held frames (nothing tracked) have no energy
        say(f"solved {len(poses)} frames, median energy {np.median(solved) if solved.size else float('nan'):.3g}")
    lap("write")
    stats.update(vertices=len(mesh.vertices), nodes=rig.graph.node_count, frames=len(take),
                 total_s=time.perf_counter() - t0)
    stages = ", ".join(f"{k[:-2]} {v:.1f}" for k, v in stats.items() if k.endswith("_s") and k != "total_s")
    say(f"wrote {args.output} ({len(take)} frames at {take.fps:g} fps; {stats['total_s']:.1f} s: {stages})")
    return 0


def _load_motions(args):
    """The take `kinetre animate` drives with, and a label: one --motion, or several joined by --map."""
    motions = args.motion if isinstance(args.motion, list) else [args.motion]
    if any(m.lower().endswith(VIDEO_EXTS) for m in motions):
        _quiet_mediapipe()
    if len(motions) > 1 and args.map is None:
        raise UsageError(f"{len(motions)} --motion given: a --map JSON says how they share the mesh "
                         f"(see docs/joint-maps.md)")
    if args.map is None:
        return _load_motion(motions[0], args.scale, as_kinect=not args.own_skeleton), motions[0]
    from .motion.jointmap import join_takes, read_joint_map
    jmap = read_joint_map(args.map)
    takes = [_load_motion(m, args.scale, as_kinect=not args.own_skeleton) for m in motions]
    return join_takes(takes, jmap), f"{' + '.join(motions)} via {args.map}"


def _write_skeleton(path: str, ext: str, take) -> None:
    if ext == ".bvh":
        from .export.bvh import write_bvh
        write_bvh(path, take.frames(), take.fps)
    else:
        from .motion.stream import write_stream
        write_stream(path, take)


# ---- capture / record ------------------------------------------------------------------------------

def cmd_capture(args) -> int:
    from .motion.capture import CaptureSettings, capture_camera, capture_video
    from .motion.stream import TakeWriter
    from .skeleton.models import KINECT20

    _ext(args.output, (".kinetre.jsonl",))
    _quiet_mediapipe()
    settings = CaptureSettings(fov_degrees=args.fov, smooth=not args.no_smooth)
    if args.video is not None:
        take = capture_video(args.video, settings, max_frames=args.max_frames, progress=not args.quiet)
        from .motion.stream import write_stream
        write_stream(args.output, take)
        tracked = take.tracked.any(axis=1).sum()
        print(f"wrote {args.output}: {len(take)} frames at {take.fps:g} fps, a person in {tracked}")
        return 0
    files = []  # the take file is created at the first frame, so a camera that fails leaves nothing behind

    def on_frame(skeleton, t):
        if not files:
            try:
                f = open(args.output, "w", encoding="utf-8")
            except OSError as e:
                raise UsageError(f"{args.output}: cannot write ({e.strerror})") from None
            files.append((f, TakeWriter(f, KINECT20, args.camera_fps, f"camera {args.camera}")))
            if not args.quiet:
                print(f"recording camera {args.camera} to {args.output} (Ctrl+C to stop)", file=sys.stderr)
        files[0][1].write(skeleton, t)

    try:
        count = capture_camera(args.camera, on_frame, settings, seconds=args.seconds, max_frames=args.max_frames)
    finally:
        for f, _ in files:
            f.close()
    if not count:
        raise UsageError(f"camera {args.camera}: no frames arrived")
    print(f"wrote {args.output}: {count} frames")
    return 0


def cmd_record(args) -> int:
    from .motion.source import resample
    from .motion.stream import write_stream

    _ext(args.output, (".kinetre.jsonl",))
    if args.source.lower().endswith(VIDEO_EXTS):
        _quiet_mediapipe()
    take = _load_motion(args.source, args.scale, as_kinect=not args.own_skeleton)
    if args.fps is not None:
        take = resample(take, args.fps)
    write_stream(args.output, take)
    print(f"wrote {args.output}: {take.model.name}, {len(take.model.joints)} joints, {len(take)} frames "
          f"at {take.fps:g} fps")
    return 0


# ---- info / graph ----------------------------------------------------------------------------------

def cmd_info(args) -> int:
    from .motion.gltf import split_animation
    path = args.path
    low = path.lower()
    if low.endswith(".bvh"):
        _info_bvh(path)
    elif low.endswith(".jsonl"):
        from .motion.stream import read_stream
        _info_take(read_stream(path), "recorded take")
    elif low.endswith(VIDEO_EXTS):
        _info_video(path)
    elif split_animation(path)[0].lower().endswith((".glb", ".gltf")):
        _info_gltf(split_animation(path)[0])
    else:
        _info_mesh(path)
    return 0


def _info_gltf(path: str) -> None:
    """A glTF: its mesh (if any) and its animations, each usable as `--motion FILE#NAME`."""
    import kinetre
    from .motion.gltf import animations, load_gltf
    anims = animations(path)
    try:
        _info_mesh(path)
    except kinetre.BadMeshError:
        if not anims:
            raise
        print(f"{path}: glTF without a mesh")
    if not anims:
        print("  animations: none")
        return
    take = load_gltf(path, 0, as_kinect=False)
    print(f"  skeleton: {len(take.model.joints)} joints ({', '.join(take.model.joints)})")
    print(f"  animations ({len(anims)}), use as --motion {os.path.basename(path)}#NAME or #INDEX:")
    for a in anims:
        print(f"    #{a.index} {a.name}: {a.duration:.2f} s, {a.channels} channels")


def _info_take(take, kind: str) -> None:
    import numpy as np
    first = take.frame(0)
    print(f"{take.source}: {kind}, skeleton {take.model.name} ({len(take.model.joints)} joints), {len(take)} frames "
          f"at {take.fps:g} fps ({take.duration:.2f} s)")
    print(f"  tracked: {100 * take.tracked.mean():.1f} % of joint-frames; first-frame height {first.height:.2f} m")
    lo, hi = np.nanmin(take.positions, axis=(0, 1)), np.nanmax(take.positions, axis=(0, 1))
    print(f"  extent (m): x {lo[0]:.2f}..{hi[0]:.2f}  y {lo[1]:.2f}..{hi[1]:.2f}  z {lo[2]:.2f}..{hi[2]:.2f}")
    print(f"  joints: {', '.join(take.model.joints)}")


def _info_bvh(path: str) -> None:
    import numpy as np

    from .motion.bvh import detect_unit, kinect_map, load_bvh, parse_bvh, rest_positions
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    clip = parse_bvh(text, path)
    per, unit = detect_unit(float(np.ptp(rest_positions(clip), axis=0).max()))
    n_end = int(clip.end_sites.sum())
    print(f"{path}: BVH, {len(clip.names) - n_end} joints + {n_end} end sites, {clip.motion.shape[1]} channels, "
          f"{len(clip.motion)} frames at {clip.fps:g} fps ({(len(clip.motion) - 1) * clip.frame_time:.2f} s)")
    print(f"  unit: {unit} ({per:.4g} m per file unit)")
    mapping = kinect_map(clip.names, clip.parents)
    if mapping is None:
        print("  Kinect-20 map: no (core joints not found by name): drives a mesh by its own bones")
    else:
        print("  Kinect-20 map: " + ", ".join(f"{k}<-{v}" for k, v in mapping[1].items()))
    _info_take(load_bvh(path), "as loaded")


def _info_video(path: str) -> None:
    import cv2
    if not os.path.exists(path):
        raise UsageError(f"{path}: no such file")
    cap = cv2.VideoCapture(path)
    if not cap.isOpened():
        raise UsageError(f"{path}: not a readable video")
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    n, fps = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)), cap.get(cv2.CAP_PROP_FPS)
    cap.release()
    print(f"{path}: video, {w}x{h}, {n} frames at {fps:g} fps ({n / fps if fps else 0:.2f} s); "
          f"`kinetre capture --video` tracks the person in it")


def _info_mesh(path: str) -> None:
    import numpy as np

    import kinetre
    mesh = kinetre.load_mesh(path)
    lo, hi = mesh.bounds
    size = hi - lo
    print(f"{path}: mesh, {len(mesh.vertices)} vertices, {len(mesh.faces)} faces, area {mesh.area:.4g}")
    print(f"  bounding box {size[0]:.4g} x {size[1]:.4g} x {size[2]:.4g} (diagonal {mesh.diagonal:.4g}), "
          f"min {np.round(lo, 4).tolist()}")
    print(f"  UVs: {'yes' if mesh.uvs is not None else 'no'}, vertex colours: "
          f"{'yes' if mesh.colors is not None else 'no'}, material: {'yes' if mesh.material is not None else 'no'}")


def cmd_graph(args) -> int:
    import kinetre
    _ext(args.output, (".ply",))
    mesh = kinetre.load_mesh(args.mesh)
    graph = kinetre.build_graph(mesh, nodes=args.nodes, seed=args.seed)
    write_graph_ply(args.output, graph)
    print(f"wrote {args.output}: {graph.node_count} nodes, {len(graph.edges)} edges "
          f"({int(graph.bridges.sum())} rigid/bridge), radius {graph.radius:.4g}")
    return 0


def write_graph_ply(path: str, graph) -> None:
    """ASCII PLY: nodes as vertices (with normals), edges as `edge` elements with a `bridge` flag."""
    lines = ["ply", "format ascii 1.0", "comment kinetre deformation graph",
             f"element vertex {graph.node_count}", "property double x", "property double y", "property double z",
             "property double nx", "property double ny", "property double nz",
             f"element edge {len(graph.edges)}", "property int vertex1", "property int vertex2",
             "property uchar bridge", "end_header"]
    lines += [" ".join(repr(float(c)) for c in (*p, *n)) for p, n in zip(graph.nodes, graph.normals)]
    lines += [f"{a} {b} {int(br)}" for (a, b), br in zip(graph.edges.tolist(), graph.bridges.tolist())]
    try:
        Path(path).write_text("\n".join(lines) + "\n", encoding="ascii")
    except OSError as e:
        raise UsageError(f"{path}: cannot write ({e.strerror})") from None


def cmd_studio(args) -> int:
    from .studio.app import run_studio
    run_studio(args.mesh, host=args.host, port=args.port, open_browser=not args.no_browser, nats=args.nats,
               room=args.room, token=_token(args), remote_scene=args.remote_scene, nkey=args.nkey)
    return 0


def _token(args) -> str | None:
    """The room token from --token or the KINETRE_TOKEN environment variable (kept out of `ps`)."""
    return args.token or os.environ.get("KINETRE_TOKEN") or None


def _add_room(p) -> None:
    p.add_argument("--nats", metavar="URL", default=None,
                   help="channels on this NATS server (nats://HOST:4222) instead of the embedded hub")
    p.add_argument("--room", default="main", help="the room's name (its subjects are kinetre.ROOM.*)")
    p.add_argument("--token", default=None, help="the room's token (or KINETRE_TOKEN); required off loopback")
    p.add_argument("--nkey", metavar="FILE", default=None,
                   help="the room's NATS nkey seed file: authenticates to NATS instead of the token "
                        "(`kinetre rooms ROOM=@FILE` makes one)")


def cmd_scene(args) -> int:
    from .studio.remote import run_scene
    if not args.nats:
        raise UsageError("kinetre scene needs --nats URL: it talks to studios only through a NATS server")
    run_scene(args.mesh, args.nats, room=args.room, token=_token(args), nodes=args.nodes,
              sample_motion=args.sample, nkey=args.nkey)
    return 0


def cmd_rooms(args) -> int:
    """Write a nats-server configuration for the given rooms (each `ROOM=TOKEN` or `ROOM=@SEED_FILE`)."""
    from .studio.natsbus import check_room, nkey_public, room_nkey, server_config
    rooms: dict[str, str] = {}
    for spec in args.rooms:
        room, sep, secret = spec.partition("=")
        if not sep or not room or not secret:
            raise UsageError(f"{spec!r}: a room is ROOM=TOKEN or ROOM=@SEED_FILE (an nkey seed, made if missing)")
        check_room(room)  # before a seed file is made for it
        if room in rooms:
            raise UsageError(f"room {room!r} is given twice")
        if secret.startswith("@"):
            seed = Path(secret[1:])
            made = not seed.exists()
            rooms[room] = room_nkey(seed) if made else nkey_public(seed)
            if not args.quiet:
                print(f"room {room}: nkey {rooms[room]} ({'new seed written to' if made else 'seed in'} {seed}:"
                      f" give it to the room's studios and scene as --nkey {seed})")
        else:
            rooms[room] = secret
    text = server_config(rooms, args.port, host=args.host)
    try:
        Path(args.output).write_text(text)
    except OSError as e:
        raise UsageError(f"{args.output}: cannot write ({e.strerror})") from None
    if not args.quiet:
        print(f"wrote {args.output}: run nats-server -c {args.output}")
    return 0


# ---- parser ----------------------------------------------------------------------------------------

def _add_scan(sub) -> None:
    """`kinetre scan` comes from kinetre.scan.cli; without open3d it explains how to install it."""
    try:
        from .scan.cli import add_scan_parser
    except ModuleNotFoundError as e:
        if e.name not in ("open3d", f"{__package__}.scan.cli"):
            raise
        missing = e.name
        p = sub.add_parser("scan", help="reconstruct a mesh from RGB-D frames (needs open3d)")
        p.add_argument("rest", nargs=argparse.REMAINDER)

        def unavailable(args):
            if missing == "open3d":
                raise UsageError("kinetre scan needs open3d: pip install 'kinetre[scan]'")
            raise UsageError("kinetre scan is not available in this installation")
        p.set_defaults(func=unavailable)
        return
    add_scan_parser(sub)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="kinetre", description="Animate any 3D mesh with a body's motion (embedded deformation).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("animate", help="drive a mesh with a motion file and write glTF, BVH, video or a take",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mesh", help="mesh file (.obj .ply .stl .off .glb .gltf, optionally .gz), or RGB-D frames "
                                "(a folder or .zip) to scan first")
    p.add_argument("--motion", required=True, action="append",
                   help="motion: .bvh, .kinetre.jsonl, a video, or a glTF animation (Fox.glb#Walk, Fox.glb#1); "
                        "repeat it with --map to join several sources")
    p.add_argument("--map", default=None, metavar="JSON",
                   help="joint map: rename, drop and pair the joints of the --motion sources (docs/joint-maps.md)")
    p.add_argument("--segment", choices=("plane", "change", "none"), default="plane",
                   help="RGB-D input: how the scan cuts out the object (default plane)")
    p.add_argument("--before", default=None, metavar="DIR",
                   help="RGB-D input with --segment change: frames of the same place without the object")
    p.add_argument("-o", "--output", required=True, help=f"output: {' '.join(ANIMATE_OUTPUTS)}")
    p.add_argument("--nodes", type=int, default=128, help="graph nodes (default 128)")
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
    p.add_argument("--scale", type=float, default=None, help="BVH: metres per file unit (default: guessed)")
    p.add_argument("--own-skeleton", action="store_true",
                   help="BVH/glTF: drive the mesh by the file's own bones, not the Kinect-20 map (unmapped files "
                        "always do)")
    p.add_argument("--fps", type=float, default=None, help="output frame rate (default: the take's, at most 30)")
    p.add_argument("--frames", default=None, metavar="START:END", help="use only these frames of the take")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many output frames")
    p.add_argument("--no-skeleton", dest="skeleton", action="store_false", help="video: do not draw the skeleton")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")
    p.set_defaults(func=cmd_animate)

    p = sub.add_parser("capture", help="track a person in a video or webcam into a .kinetre.jsonl take",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--video", help="video file")
    src.add_argument("--camera", type=int, help="camera index (0 = the first webcam)")
    p.add_argument("-o", "--output", required=True, help="output .kinetre.jsonl")
    p.add_argument("--seconds", type=float, default=None, help="camera: stop after this long (default: Ctrl+C)")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    p.add_argument("--camera-fps", type=float, default=30.0, help="camera: nominal frame rate written (default 30)")
    p.add_argument("--fov", type=float, default=60.0, help="camera horizontal field of view, degrees (default 60)")
    p.add_argument("--no-smooth", action="store_true", help="no One-Euro filtering")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_capture)

    p = sub.add_parser("record", help="convert any motion (BVH, take, video) to a .kinetre.jsonl take")
    p.add_argument("source", help="motion: .bvh, .kinetre.jsonl or a video")
    p.add_argument("-o", "--output", required=True, help="output .kinetre.jsonl")
    p.add_argument("--scale", type=float, default=None, help="BVH: metres per file unit (default: guessed)")
    p.add_argument("--fps", type=float, default=None, help="resample to this frame rate")
    p.add_argument("--own-skeleton", action="store_true", help="BVH: keep the file's hierarchy, no Kinect-20 map")
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("info", help="what a mesh, BVH, take or video holds")
    p.add_argument("path")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("graph", help="build a mesh's deformation graph and write it as PLY for inspection")
    p.add_argument("mesh")
    p.add_argument("-o", "--output", required=True, help="output .ply (nodes = vertices, edges with a bridge flag)")
    p.add_argument("--nodes", type=int, default=128)
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_graph)

    p = sub.add_parser("studio", help="the live studio in a browser")
    p.add_argument("mesh", nargs="?", default=None, help="mesh to open (default: the bundled Spot)")
    p.add_argument("--port", type=int, default=8000)
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    _add_room(p)
    p.add_argument("--remote-scene", action="store_true",
                   help="no scene in this server: a `kinetre scene` process on the same NATS room solves")
    p.set_defaults(func=cmd_studio)

    p = sub.add_parser("scene", help="a headless scene: solves a room's skeletons over NATS, publishes transforms")
    p.add_argument("mesh", nargs="?", default=None, help="mesh to load (default: the bundled Spot)")
    p.add_argument("--nodes", type=int, default=128, help="graph nodes (default 128)")
    p.add_argument("--sample", action="store_true", help="play the bundled walk as a capture client")
    _add_room(p)
    p.set_defaults(func=cmd_scene)

    p = sub.add_parser("rooms", help="write a nats-server configuration: one user per room, confined to its subjects")
    p.add_argument("rooms", nargs="+", metavar="ROOM=SECRET",
                   help="ROOM=TOKEN (a password) or ROOM=@FILE (an nkey seed file; a new one is made if missing)")
    p.add_argument("-o", "--output", required=True, help="the configuration file to write (nats-server -c FILE)")
    p.add_argument("--port", type=int, default=4222, help="the port nats-server listens on (default 4222)")
    p.add_argument("--host", default="127.0.0.1", help="the address nats-server binds (default 127.0.0.1)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_rooms)

    _add_scan(sub)
    from .face.cli import add_face_parser
    add_face_parser(sub)
    from .avatar.cli import add_avatar_parser
    add_avatar_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line `argv` (default: this process's own, which then exits with the result)."""
    try:
        return _run(argv)
    finally:
        if argv is None:
            # The process exits next. Its shutdown collections would walk every object still alive (numba's
            # typing tables, ~160k objects after an animate): 0.3-0.7 s of a 3 s command. Those collections
            # skip frozen objects; atexit handlers, output flushing and module teardown run as usual.
            gc.freeze()


def _run(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KinetreError as e:
        print(f"kinetre: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 2
    except (FileNotFoundError, PermissionError, IsADirectoryError) as e:
        name = e.filename or ""
        print(f"kinetre: error: {name}: {e.strerror or e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("kinetre: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `kinetre info x.bvh | head`: the reader left, which is not an error
        sys.stdout = open(os.devnull, "w")
        return 0


if __name__ == "__main__":
    sys.exit(main())
