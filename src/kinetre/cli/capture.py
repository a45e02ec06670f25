"""`kinetre capture --video CLIP | --camera N -o take.kinetre.jsonl`: everyone in view (up to four people,
their hands and faces) tracked into a take."""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np

from .common import EPILOG, UsageError, output_ext, prepare_mediapipe


def register(sub) -> None:
    """Add `kinetre capture` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("capture", help="track people (bodies, hands, faces) in a video or webcam into a "
                                       ".kinetre.jsonl take",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--video", help="video file")
    src.add_argument("--camera", type=int, help="camera index (0 = the first webcam)")
    p.add_argument("-o", "--output", required=True, help="output .kinetre.jsonl")
    p.add_argument("--seconds", type=float, default=None, help="camera: stop after this long (default: Ctrl+C)")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    p.add_argument("--camera-fps", type=float, default=30.0, help="camera: nominal frame rate written (default 30)")
    p.add_argument("--fov", type=float, default=60.0, help="camera horizontal field of view, degrees (default 60)")
    p.add_argument("--no-smooth", action="store_true", help="no One-Euro filtering (feet are still held)")
    p.add_argument("--raw", action="store_true",
                   help="write the take as tracked: no smoothing, no foot contact (by default a video is smoothed "
                        "without lag and its feet held on the floor; a camera likewise, live)")
    p.add_argument("--people", type=int, default=4, help="most people tracked at once, 1 to 4 (default 4)")
    p.add_argument("--no-hands", action="store_true", help="do not track hands")
    p.add_argument("--no-face", action="store_true", help="do not track faces (blendshapes)")
    p.add_argument("--no-tiles", action="store_true",
                   help="search the whole frame only, not also its overlapping squares (faster; misses small people)")
    p.add_argument("--every", type=int, default=1, metavar="N", help="video: track every N-th frame (default 1)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_capture)


def cmd_capture(args) -> int:
    from ..motion.capture import CaptureSettings, capture_camera, capture_video
    from ..motion.stream import TakeWriter
    from ..skeleton.models import KINECT20, Skeleton

    output_ext(args.output, (".kinetre.jsonl",))
    prepare_mediapipe()
    from ..motion.cleanup import CleanupSettings, LiveCleaner, clean_take
    # the tracker's own causal filter only for a raw take that still wants smoothing: cleaning smooths better
    settings = CaptureSettings(fov_degrees=args.fov, smooth=args.raw and not args.no_smooth, people=args.people,
                               hands=not args.no_hands, face=not args.no_face, tiles=not args.no_tiles)
    cleanup = CleanupSettings(smooth=not args.no_smooth)
    if args.video is not None:
        take = capture_video(args.video, settings, max_frames=args.max_frames, progress=not args.quiet,
                             every=args.every)
        if not args.raw:
            take = clean_take(take, cleanup)
        from ..motion.stream import write_stream
        write_stream(args.output, take)
        tracked = take.tracked.any(axis=1).sum()
        extras = [f"{len(take.people)} people (ids {', '.join(map(str, take.people))})"] if take.people else []
        if take.hands is not None:
            extras.append(f"hands in {int(np.isfinite(take.hands).all(axis=(3, 4)).any(axis=(1, 2)).sum())}")
        if take.blendshapes is not None:
            extras.append(f"a face in {int(np.isfinite(take.blendshapes).all(axis=2).any(axis=1).sum())}")
        done = [k for k in ("smoothing", "contact") if k in (take.applied or {})]
        if done:
            extras.append(f"cleaned by {' and '.join(done)} (--raw: as tracked)")
        print(f"wrote {args.output}: {len(take)} frames at {take.fps:g} fps, a person in {tracked}"
              + "".join(f", {e}" for e in extras))
        return 0
    files = []  # the take file is created at the first frame, so a camera that fails leaves nothing behind
    cleaners: dict[int, LiveCleaner] = {}

    def clean(skeleton, t, pid):
        if pid not in cleaners:
            cleaners[pid] = LiveCleaner(KINECT20, cleanup, viewpoint=np.zeros(3))  # the camera's origin
        pos = cleaners[pid](skeleton.positions, t)
        return Skeleton(KINECT20, pos, np.isfinite(pos).all(axis=1))

    def on_frame(skeleton, t, people):
        if not args.raw:
            main = next((k for k, p in enumerate(people) if p.skeleton is skeleton), None)
            people = tuple(replace(p, skeleton=clean(p.skeleton, t, p.id)) for p in people)
            skeleton = skeleton if main is None else people[main].skeleton
        if not files:
            try:
                f = open(args.output, "w", encoding="utf-8")
            except OSError as e:
                raise UsageError(f"{args.output}: cannot write ({e.strerror})") from None
            applied = None if args.raw else LiveCleaner(KINECT20, cleanup).describe()
            files.append((f, TakeWriter(f, KINECT20, args.camera_fps, f"camera {args.camera}",
                                        settings.blendshape_names, applied)))
            if not args.quiet:
                print(f"recording camera {args.camera} to {args.output} (Ctrl+C to stop)", file=sys.stderr)
        files[0][1].write(skeleton, t, people)

    try:
        count = capture_camera(args.camera, on_frame, settings, seconds=args.seconds, max_frames=args.max_frames)
    finally:
        for f, _ in files:
            f.close()
    if not count:
        raise UsageError(f"camera {args.camera}: no frames arrived")
    print(f"wrote {args.output}: {count} frames")
    return 0
