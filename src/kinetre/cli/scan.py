"""`kinetre scan frames/ -o out.ply [--segment plane|change|none --before DIR] [--voxel 0.006] ...`

`register(subparsers)` adds the subcommand to the main `kinetre` parser; its handler takes the
parsed namespace and returns the exit code (0 done, 2 bad input with one line on stderr).
"""
from __future__ import annotations

import argparse
import sys

from ..errors import KinetreError
from .common import add_scan_options, scan_options


def register(sub) -> None:
    """Add `kinetre scan` to the `kinetre` parser's subcommands."""
    parser = sub.add_parser(
        "scan", help="reconstruct a mesh from RGB-D frames (TUM or Redwood folder)",
        description="Track RGB-D frames by frame-to-model ICP, fuse them into a TSDF, cut out the object and "
                    "write a clean mesh (metres, +Y up) ready for `kinetre` rigging.")
    parser.add_argument("frames", help="folder with rgb.txt + depth.txt (TUM) or color/ + depth/ (Redwood)")
    parser.add_argument("-o", "--output", required=True, help="mesh to write: .ply, .obj or .glb")
    add_scan_options(parser, segment="none")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=run_scan)


def run_scan(args: argparse.Namespace) -> int:
    """Handler of `kinetre scan`: prints the report and the summary line; returns the exit code."""
    from ..scan.pipeline import scan
    try:
        result = scan(args.frames, args.output, **scan_options(args), progress=not args.quiet)
    except KinetreError as exc:
        print(f"kinetre scan: {exc}", file=sys.stderr)
        return 2
    for line in result.report:  # where the surface went: frames, fusion, components, what was kept and why
        print(line)
    for line in result.warnings:
        print(f"kinetre scan: warning: {line}", file=sys.stderr)
    print(result.summary())
    return 0
