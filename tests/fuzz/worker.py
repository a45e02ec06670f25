"""The fuzz harness's reader process: reads one case per line on stdin, runs the readers a user's command or
the studio would run on it, and answers one line per case on stdout.

A case is {"reader": name, "files": {relative path: base64 bytes}, "main": relative path}; the answer is
{"status": "ok" | "refused" | "bug", "detail": str}. "refused" is a KinetreError (the one-line message the
command line prints), "bug" any other exception (a traceback a user would see). A native crash or a hang
ends or stalls this process, which the harness (run.py) sees from outside.
"""
from __future__ import annotations

import base64
import contextlib
import io
import json
import os
import shutil
import sys
import tempfile
import traceback
import warnings
from pathlib import Path


def _cli(*argv: str) -> None:
    """A `kinetre` command in this process: exit 0 or 2 (a KinetreError, printed as one line) are answers."""
    from kinetre.cli.main import main
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(list(argv))
    if code == 2:
        lines = err.getvalue().strip().splitlines()
        if len(lines) != 1:
            raise AssertionError(f"exit 2 with {len(lines)} lines on stderr: {err.getvalue()!r}")
        from kinetre.errors import KinetreError
        raise KinetreError(lines[0])
    if code != 0:
        raise AssertionError(f"kinetre {' '.join(argv)} exited {code}: {err.getvalue()!r}")


def read_mesh(path: Path) -> None:
    """`kinetre info`, then what a studio upload does next: stand it up and build its graph."""
    _cli("info", str(path))
    from kinetre.mesh.load import load_mesh
    from kinetre.studio.meshes import prepare_upright
    prepare_upright(load_mesh(path), str(path), nodes=24)


def read_gltf(path: Path) -> None:
    """`kinetre info` (mesh, avatar map, animations), then the motion `animate --motion` and `avatar` read."""
    _cli("info", str(path))
    from kinetre.avatar.bonemap import auto_map
    from kinetre.avatar.load import load_avatar
    from kinetre.errors import KinetreError
    from kinetre.motion.gltf import load_gltf
    try:
        take = load_gltf(path)
        take.frame(len(take) - 1)
    except KinetreError:
        pass
    auto_map(load_avatar(path))


def read_bvh(path: Path) -> None:
    _cli("info", str(path))


def read_take(path: Path) -> None:
    _cli("info", str(path))


def read_intrinsics(path: Path) -> None:
    from kinetre.scan.frames import read_intrinsics as read
    read(path, (40, 30))


def read_rgbd(path: Path) -> None:
    """The frames a scan reads, fused by Open3D with the folder's intrinsics (integration, a ray cast, marching
    cubes: the native steps of `kinetre scan`, without its slow tracking)."""
    import numpy as np

    from kinetre.scan.frames import open_sequence, read_frame
    from kinetre.scan.fuse import TSDFVolume
    sequence = open_sequence(path)
    volume = TSDFVolume(0.05, block_count=2000)
    for i in range(len(sequence)):
        color, depth = read_frame(sequence, i)
        volume.integrate(color, depth, sequence.intrinsics, np.eye(4))
    volume.raycast_depth(sequence.intrinsics, np.eye(4))
    volume.triangle_mesh()


def read_message(path: Path) -> None:
    """The studio's parser on one client message, and each field reader its commands use."""
    from kinetre.studio import protocol
    msg = protocol.parse_message(path.read_bytes())
    kind = msg["type"]
    try:
        if kind == "skeleton":
            protocol.parse_frame(msg)
        protocol.parse_person(msg)
        protocol.parse_mesh(msg)
    except protocol.ProtocolError as e:
        from kinetre.errors import KinetreError
        raise KinetreError(str(e)) from None


READERS = {"mesh": read_mesh, "gltf": read_gltf, "bvh": read_bvh, "take": read_take,
           "intrinsics": read_intrinsics, "rgbd": read_rgbd, "message": read_message}


def run(case: dict) -> dict:
    from kinetre.errors import KinetreError
    from kinetre.studio.protocol import ProtocolError
    folder = Path(tempfile.mkdtemp(prefix="kinetre-fuzz-"))
    try:
        for name, data in case["files"].items():
            target = folder / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(base64.b64decode(data))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                READERS[case["reader"]](folder / case["main"])
        except (KinetreError, ProtocolError) as e:
            message = " ".join(str(e).split())
            return {"status": "refused", "detail": message}
        except Exception as e:  # noqa: BLE001 - any other exception is what the fuzzer looks for
            return {"status": "bug", "detail": f"{type(e).__name__}: {e}\n{traceback.format_exc(limit=-6)}"}
        return {"status": "ok", "detail": ""}
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def main() -> None:
    # answers go to a private copy of stdout; fd 1 becomes stderr, so prints of Python and of native
    # libraries (Open3D writes to the C stdout) cannot corrupt them
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    for line in sys.stdin:
        answer = run(json.loads(line))
        out.write(json.dumps(answer) + "\n")
        out.flush()


if __name__ == "__main__":
    main()
