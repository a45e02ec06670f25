"""`kinetre kernels`: compile the numeric kernels once, ahead of the first real command (`make setup` runs it).

It animates the packaged cow with the packaged walk the ways a first `kinetre animate` goes (a mesh not seen
before, then its kept preprocessing; a graph of over 255 nodes, whose joints glTF indexes with 16 bits), which fills numba's cache with every kernel
those runs use, then compiles the signatures they used into the extension module that later commands load
without numba (kinetre.compiled). Whatever else a command needs still comes from numba's cache, or is
compiled on first use with one progress line.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from importlib import resources
from pathlib import Path

RUNS = ([], ["--no-cache"], [], ["--no-cache", "--nodes", "320"])  # kept (written, then read) and fresh


def register(sub) -> None:
    """Add `kinetre kernels` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("kernels", help="compile the numeric kernels ahead of time (once per version; "
                                       "`make setup` does it): the first animate then starts in about a second")
    p.add_argument("-q", "--quiet", action="store_true", help="no summary")
    p.set_defaults(func=cmd_kernels)


def cmd_kernels(args) -> int:
    from ..compiled import export_compiled
    from ..jit import load_numba
    from . import animate

    if not args.quiet:
        print("compiling the numeric kernels (up to two minutes the first time)", flush=True)
    load_numba()  # every kernel is numba's own from here: the runs below compile into (or load from) its cache
    data = resources.files("kinetre") / "data"
    mesh, walk = str(data / "spot.obj"), str(data / "cmu_12_01_walk.bvh")
    parser = argparse.ArgumentParser(prog="kinetre")
    animate.register(parser.add_subparsers())
    notes = io.StringIO()  # the cow is no match for the walk: its notes would only puzzle whoever reads them
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stderr(notes):
        for extra in RUNS:
            animate.cmd_animate(parser.parse_args(["animate", mesh, "--motion", walk, "-o", str(Path(tmp) / "warm.glb"),
                                           "--max-frames", "8", "-q", *extra]))
    folder, count = export_compiled()
    if not args.quiet:
        print(f"compiled {count} kernel signatures into {folder}")
    return 0
