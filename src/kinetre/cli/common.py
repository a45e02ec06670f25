"""What the command-line commands share: the usage error, output types, frame ranges, motion loading, the
examples under `--help`, the RGB-D scan options (`kinetre scan`, `kinetre animate FRAMES/`) and the room
options of the networked commands."""
from __future__ import annotations

import os

from ..errors import KinetreError

EPILOG = """examples:
  kinetre animate chair.obj --motion walk.bvh -o chair_walk.glb
  kinetre animate lamp.obj --motion walk.bvh --subset "HipCenter,right arm" -o lamp.mp4
  kinetre animate spot.obj --motion take.kinetre.jsonl --fit --yaw 90 -o spot.glb
  kinetre animate horse.ply --motion Fox.glb#Walk -o horse.glb
  kinetre animate horse.ply --motion a.bvh --motion b.bvh --map two-people.json -o horse.glb
  kinetre animate frames/ --motion walk.bvh -o scan_walk.glb
  kinetre animate spider.obj --motion take.kinetre.jsonl --hand right -o spider.glb
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

VIDEO_EXTS = (".mp4", ".mov", ".avi", ".mkv", ".webm")


class UsageError(KinetreError):
    """A command-line argument that does not make sense (reported like any bad input)."""


def output_ext(path: str, choices) -> str:
    """The output type of `path` among `choices` (longest match first: `.kinetre.jsonl` before `.jsonl`)."""
    low = path.lower()
    for ext in sorted(choices, key=len, reverse=True):
        if low.endswith(ext):
            return ext
    raise UsageError(f"{path}: unsupported output type (expected {', '.join(choices)})")


def frame_range(spec: str | None) -> slice:
    """`--frames START:END` (either end may be empty) as a slice; no spec is every frame."""
    if not spec:
        return slice(None)
    parts = spec.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        start, stop = (int(p) if p.strip() else None for p in parts)
    except ValueError:
        raise UsageError(f"--frames must be START:END (e.g. 0:60), got {spec!r}") from None
    return slice(start, stop)


def load_motion(path: str, scale: float | None, as_kinect: bool = True):
    """A motion file (BVH, glTF animation, recorded take, video) as a Take; `--scale` and `--own-skeleton`
    apply only where the file has a skeleton of its own. A video is tracked unfiltered: `cleaned` smooths it
    afterwards without lag."""
    from ..motion.gltf import is_gltf
    from ..motion.source import load_take
    if path.lower().endswith(VIDEO_EXTS) and scale is None and as_kinect:
        from ..motion.capture import CaptureSettings, capture_video
        return capture_video(path, CaptureSettings(smooth=False))
    if is_gltf(path):
        if scale is not None:
            raise UsageError("--scale applies to BVH files only")
        return load_take(path, as_kinect=as_kinect)
    if not path.lower().endswith(".bvh") and (scale is not None or not as_kinect):
        raise UsageError("--scale and --own-skeleton apply to BVH and glTF files only")
    if path.lower().endswith(".bvh"):
        return load_take(path, scale=scale, as_kinect=as_kinect)
    return load_take(path)


def add_cleanup_options(p) -> None:
    """--raw, --contact and --report: how a take is cleaned before it drives, and the quality report."""
    p.add_argument("--raw", action="store_true",
                   help="use a camera take as tracked: no smoothing, no foot contact (both on by default)")
    p.add_argument("--contact", action="store_true",
                   help="mocap: hold the feet where they stand on the floor (camera takes get it by default)")
    p.add_argument("--report", default=None, metavar="JSON",
                   help="write the motion's quality (jitter, foot skate, ground, lag) before and after, as JSON")


def add_live_cleanup_options(p) -> None:
    """--raw and --contact for a live scene: how users' frames are cleaned before the solve."""
    p.add_argument("--raw", action="store_true",
                   help="solve camera users' frames as tracked: no smoothing, no foot contact (both on by default)")
    p.add_argument("--contact", action="store_true",
                   help="also hold the feet of mocap users (the sample motion, VMC performers) on the room's floor")


def live_cleanup(args) -> dict:
    """The `clean` and `contact` keywords of a live scene from --raw and --contact."""
    if args.raw and args.contact:
        raise UsageError("--raw and --contact contradict each other: give one")
    return {"clean": not args.raw, "contact": args.contact}


def cleaned(take, args, say):
    """The take smoothed and its feet held (kinetre.motion.cleanup) when it is a camera take (unless --raw)
    or --contact asks (contact only: mocap is smooth already); as it is when it records a cleaning already."""
    from ..motion.cleanup import CleanupSettings, clean_take
    from ..motion.take import is_camera_take
    if args.raw and args.contact:
        raise UsageError("--raw and --contact contradict each other: give one")
    camera = is_camera_take(take)
    if args.raw or take.applied is not None or not (camera or args.contact):
        return take
    out = clean_take(take, CleanupSettings(smooth=camera))
    done = [k for k in ("smoothing", "contact") if k in (out.applied or {})]
    lag = ((out.applied or {}).get("smoothing") or {}).get("lag_ms")
    say(f"cleaned the take: {' and '.join(done)}" + (f", lag {lag:.0f} ms" if lag is not None else "")
        + " (--raw: as tracked)" * camera)
    return out


def write_report(path: str, report: dict) -> None:
    """Write a quality report as JSON (NaN as null)."""
    import json
    try:
        with open(path, "w", encoding="utf-8") as f:
            json.dump(report, f, indent=1, allow_nan=False)
            f.write("\n")
    except OSError as e:
        raise UsageError(f"{path}: cannot write the report ({e.strerror})") from None


def prepare_mediapipe() -> None:
    """MediaPipe ready for a command that tracks: its models fetched on first use (saying so), its logging quiet."""
    from ..motion.fetch_models import ensure_models
    ensure_models()
    quiet_mediapipe()


def quiet_mediapipe() -> None:
    """Keep a command's stderr for its errors: MediaPipe's C++ side logs through glog/absl there."""
    os.environ.setdefault("GLOG_minloglevel", "2")
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")


def room_token(args) -> str | None:
    """The room token from --token or the KINETRE_TOKEN environment variable (kept out of `ps`)."""
    return args.token or os.environ.get("KINETRE_TOKEN") or None


def add_room_options(p) -> None:
    """--nats, --room, --token and --nkey: which room of which NATS server a networked command joins."""
    p.add_argument("--nats", metavar="URL", default=None,
                   help="channels on this NATS server (nats://HOST:4222) instead of the embedded hub")
    p.add_argument("--room", default="main", help="the room's name (its subjects are kinetre.ROOM.*)")
    p.add_argument("--token", default=None, help="the room's token (or KINETRE_TOKEN); required off loopback")
    p.add_argument("--nkey", metavar="FILE", default=None,
                   help="the room's NATS nkey seed file: authenticates to NATS instead of the token "
                        "(`kinetre rooms ROOM=@FILE` makes one)")


# option (its argparse name) -> the `kinetre.scan.pipeline.scan` keyword it sets
SCAN_KEYWORDS = {"voxel": "voxel", "intrinsics": "intrinsics", "camera": "camera", "depth_scale": "depth_scale",
                 "depth_max": "depth_max", "faces": "target_faces", "threads": "threads"}


def add_scan_options(p, segment: str) -> None:
    """The RGB-D scan's options, one group with the same flags and help wherever frames are scanned;
    `segment` is the command's default cut ("plane", "change" or "none")."""
    from ..scan.frames import CAMERAS
    g = p.add_argument_group("RGB-D frames", "how a folder (or .zip) of RGB-D frames is scanned into a mesh")
    g.add_argument("--segment", choices=("plane", "change", "none"), default=segment,
                   help=f"plane: remove the supporting plane; change: keep what differs from --before; none: the "
                        f"whole scene (default {segment})")
    g.add_argument("--before", metavar="DIR", help="frames of the same place without (or with) the object")
    g.add_argument("--voxel", type=float, metavar="M", help="TSDF voxel size in metres (default 0.006)")
    g.add_argument("--intrinsics", metavar="FILE",
                   help="Open3D PinholeCameraIntrinsic JSON or a 3x3 matrix TXT (default: the folder's)")
    g.add_argument("--camera", choices=sorted(CAMERAS), help="named camera defaults when no intrinsics file")
    g.add_argument("--depth-scale", type=float, metavar="S",
                   help="raw depth units per metre (default 1000; 5000 for a TUM layout)")
    g.add_argument("--depth-max", type=float, metavar="M", help="ignore depth beyond this, in metres (default 3)")
    g.add_argument("--faces", type=int, metavar="N", help="decimate the scan to about N faces")
    g.add_argument("--threads", type=int, metavar="N", help="CPU threads for Open3D (default 1)")


def scan_options(args) -> dict:
    """`kinetre.scan.pipeline.scan`'s keywords from the options of `add_scan_options`: the cut (None for
    "none"), the frames before, and each option given (one not given keeps the scan's default)."""
    given = {key: getattr(args, name) for name, key in SCAN_KEYWORDS.items() if getattr(args, name) is not None}
    return {"segment": None if args.segment == "none" else args.segment, "before": args.before, **given}
