"""`kinetre scan frames/ -o out.ply [--segment plane|change --before DIR] [--voxel 0.006] ...`

`register(subparsers)` adds the subcommand to the main `kinetre` parser; its handler takes the
parsed namespace and returns the exit code (0 done, 2 bad input with one line on stderr).
"""
from __future__ import annotations

import argparse
import sys

from ..errors import KinetreError
from ..scan.frames import CAMERAS


def register(sub) -> None:
    """Add `kinetre scan` to the `kinetre` parser's subcommands."""
    parser = sub.add_parser(
        "scan", help="reconstruct a mesh from RGB-D frames (TUM or Redwood folder)",
        description="Track RGB-D frames by frame-to-model ICP, fuse them into a TSDF, cut out the object and "
                    "write a clean mesh (metres, +Y up) ready for `kinetre` rigging.")
    parser.add_argument("frames", help="folder with rgb.txt + depth.txt (TUM) or color/ + depth/ (Redwood)")
    parser.add_argument("-o", "--output", required=True, help="mesh to write: .ply, .obj or .glb")
    parser.add_argument("--segment", choices=("plane", "change"),
                        help="plane: remove the supporting plane; change: keep what differs from --before")
    parser.add_argument("--before", metavar="DIR", help="frames of the same place without (or with) the object")
    parser.add_argument("--voxel", type=float, default=0.006, help="TSDF voxel size in metres (default 0.006)")
    parser.add_argument("--intrinsics", metavar="FILE",
                        help="Open3D PinholeCameraIntrinsic JSON or a 3x3 matrix TXT (default: the folder's)")
    parser.add_argument("--camera", choices=sorted(CAMERAS), help="named camera defaults when no intrinsics file")
    parser.add_argument("--depth-scale", type=float, metavar="S",
                        help="raw depth units per metre (default 1000; 5000 for TUM)")
    parser.add_argument("--depth-max", type=float, default=3.0, help="ignore depth beyond this (metres)")
    parser.add_argument("--faces", type=int, metavar="N", help="decimate to about N faces")
    parser.add_argument("--threads", type=int, default=1, help="CPU threads for Open3D (default 1)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=run_scan)


def run_scan(args: argparse.Namespace) -> int:
    """Handler of `kinetre scan`: prints the report and the summary line; returns the exit code."""
    from ..scan.pipeline import scan
    try:
        result = scan(args.frames, args.output, segment=args.segment, before=args.before, voxel=args.voxel,
                      intrinsics=args.intrinsics, camera=args.camera, depth_scale=args.depth_scale,
                      depth_max=args.depth_max, target_faces=args.faces, threads=args.threads,
                      progress=not args.quiet)
    except KinetreError as exc:
        print(f"kinetre scan: {exc}", file=sys.stderr)
        return 2
    for line in result.report:  # where the surface went: frames, fusion, components, what was kept and why
        print(line)
    for line in result.warnings:
        print(f"kinetre scan: warning: {line}", file=sys.stderr)
    print(result.summary())
    return 0
