"""`kinetre record MOTION -o take.kinetre.jsonl`: any motion source (BVH, glTF, take, video) as a take."""
from __future__ import annotations

from .common import VIDEO_EXTS, load_motion, output_ext, prepare_mediapipe


def register(sub) -> None:
    """Add `kinetre record` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("record", help="convert any motion (BVH, take, video) to a .kinetre.jsonl take")
    p.add_argument("source", help="motion: .bvh, .kinetre.jsonl or a video")
    p.add_argument("-o", "--output", required=True, help="output .kinetre.jsonl")
    p.add_argument("--scale", type=float, default=None, help="BVH: metres per file unit (default: guessed)")
    p.add_argument("--fps", type=float, default=None, help="resample to this frame rate")
    p.add_argument("--own-skeleton", action="store_true", help="BVH: keep the file's hierarchy, no Kinect-20 map")
    p.set_defaults(func=cmd_record)


def cmd_record(args) -> int:
    from ..motion.source import resample
    from ..motion.stream import write_stream

    output_ext(args.output, (".kinetre.jsonl",))
    if args.source.lower().endswith(VIDEO_EXTS):
        prepare_mediapipe()
    take = load_motion(args.source, args.scale, as_kinect=not args.own_skeleton)
    if args.fps is not None:
        take = resample(take, args.fps)
    write_stream(args.output, take)
    print(f"wrote {args.output}: {take.model.name}, {len(take.model.joints)} joints, {len(take)} frames "
          f"at {take.fps:g} fps")
    return 0
