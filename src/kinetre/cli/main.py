"""The `kinetre` parser and entry point: every command module registers its subcommand, and bad input ends as
one line on stderr and exit status 2."""
from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys

from ..errors import KinetreError
from .common import EPILOG, UsageError


# every command by its module in this package, in the order `kinetre --help` lists them
COMMANDS = {"animate": "animate", "capture": "capture", "record": "record", "info": "info", "graph": "graph",
            "studio": "studio", "scene": "scene", "rooms": "rooms", "models": "models", "kernels": "kernels",
            "blender-addon": "blender", "scan": "scan", "face": "face", "avatar": "avatar"}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The `kinetre` parser with every command, or with only `command` when it names one: a command line
    then imports its own command's module and not the others' (0.03 s of a one-second animate)."""
    parser = argparse.ArgumentParser(
        prog="kinetre", description="Animate any 3D mesh with a body's motion (embedded deformation).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module in COMMANDS.items():
        if command in COMMANDS and name != command:
            continue
        if name == "scan":
            _add_scan(sub)
        else:
            importlib.import_module(f"{__package__}.{module}").register(sub)
    return parser


def _add_scan(sub) -> None:
    """`kinetre scan` comes from kinetre.cli.scan; without the scan stage it explains how to install it."""
    try:
        from .scan import register
    except ModuleNotFoundError as e:
        if e.name not in ("open3d", "kinetre.scan", "kinetre.scan.frames"):
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
    register(sub)


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
    words = sys.argv[1:] if argv is None else argv
    parser = build_parser(words[0] if words else None)
    args = parser.parse_args(argv)
    if not getattr(args, "quiet", False) and sys.stderr.isatty():  # a progress line, as the bars are
        from ..compile_notice import announce_compiling
        announce_compiling(lambda line: print(line, file=sys.stderr, flush=True))
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
