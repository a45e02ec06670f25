"""FBX, the format Unity and Unreal users ask for first, written by Blender's own exporter: Kinetre writes the
rigged glTF (every joint exact: `stretch=True`), a background Blender imports it and exports FBX
(fbx_in_blender.py). Where Blender is not installed the command says so before doing any work.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from ..errors import ExportError

SCRIPT = Path(__file__).resolve().parent / "fbx_in_blender.py"


def blender_program() -> str | None:
    """The Blender to run: $KINETRE_BLENDER if set, else `blender` on PATH; None when there is none."""
    named = os.environ.get("KINETRE_BLENDER")
    if named:
        return named if os.path.isfile(named) and os.access(named, os.X_OK) else None
    return shutil.which("blender")


def check_fbx(path) -> str:
    """The Blender that will write FBX file `path`, or ExportError saying that FBX needs one."""
    program = blender_program()
    if program is None:
        where = (f"$KINETRE_BLENDER names {os.environ['KINETRE_BLENDER']}, which is not a program"
                 if os.environ.get("KINETRE_BLENDER") else "no `blender` on PATH")
        raise ExportError(f"{path}: FBX is written through Blender's own exporter and Blender is not installed "
                          f"({where}; install Blender 3.4+ or set KINETRE_BLENDER), or write .glb instead")
    return program


def gltf_to_fbx(gltf, fbx, fps: float, timeout: float = 1800) -> None:
    """Convert the rigged, animated `gltf` into `fbx` with Blender's importer and exporter at `fps`."""
    program = check_fbx(fbx)
    fbx = Path(fbx)
    try:
        fbx.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ExportError(f"{fbx}: cannot write the FBX file ({e.strerror or e})") from None
    run = subprocess.run([program, "-b", "--factory-startup", "--python", str(SCRIPT), "--", str(gltf), str(fbx),
                          f"{fps:g}"], stdin=subprocess.DEVNULL, capture_output=True, text=True,
                         errors="replace", timeout=timeout)
    said = [ln for ln in run.stdout.splitlines() if ln.startswith("kinetre-fbx: ")]
    if run.returncode != 0 or not said or said[-1] != "kinetre-fbx: ok" or not fbx.is_file():
        why = said[-1].removeprefix("kinetre-fbx: ") if said else f"Blender exited with status {run.returncode}"
        raise ExportError(f"{fbx}: Blender ({program}) could not write the FBX file: {why}")


@contextlib.contextmanager
def gltf_or_fbx(output, fps: float):
    """Yields the path a glTF writer writes to: `output` itself, or for an .fbx a temporary .glb that
    Blender then converts into `output`."""
    output = Path(output)
    if output.suffix.lower() != ".fbx":
        yield output
        return
    with tempfile.TemporaryDirectory(prefix="kinetre-fbx-") as tmp:
        glb = Path(tmp) / (output.stem + ".glb")
        yield glb
        gltf_to_fbx(glb, output, fps)
