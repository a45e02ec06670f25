"""Mesh uploads as jobs: a worker thread prepares the mesh while the page polls the job's stage.

An uploaded file is read (a .zip of RGB-D frames, TUM or Redwood layout, is scanned into a mesh first),
stood in metres and given its graph off the event loop; the result is handed back to the loop, which swaps
it into the scene. A failure becomes the job's readable error, never a dead progress bar.
"""
from __future__ import annotations

import asyncio
import itertools
import os
import shutil
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..errors import KinetreError
from ..mesh.load import load_mesh
from .meshes import prepare_upright

MAX_UPLOAD = 200 * 1024 * 1024


@dataclass
class Job:
    id: int
    name: str
    stage: str = "uploaded"
    fraction: float = 0.0
    error: str = ""
    done: bool = False
    mesh_id: int | None = None  # the mesh it made, once done


    def failed(self, error: str) -> None:
        self.error, self.stage, self.done = error, "failed", True

    def status(self) -> dict:
        return {"stage": self.stage, "fraction": self.fraction, "error": self.error, "done": self.done,
                "mesh": self.mesh_id}


class Jobs:
    """The jobs of one studio (or scene), by id."""

    def __init__(self):
        self._jobs: dict[int, Job] = {}
        self._ids = itertools.count(1)

    def new(self, name: str) -> Job:
        job = Job(next(self._ids), name)
        self._jobs[job.id] = job
        return job

    def get(self, job_id: int) -> Job | None:
        return self._jobs.get(job_id)


def prepare_upload(job: Job, data: bytes, nodes: int, loop: asyncio.AbstractEventLoop,
                   ready: Callable[..., None], scan_options: dict | None = None) -> None:
    """Prepare the uploaded bytes in a worker thread; `ready(mesh, graph, name, upright, raw)` then runs in
    `loop` (`raw`: the mesh as loaded, before it was stood upright)."""
    folder = Path(tempfile.mkdtemp(prefix="kinetre-upload-"))
    path = folder / (Path(job.name).name or "mesh")
    path.write_bytes(data)

    def progress(stage: str, fraction: float) -> None:
        job.stage, job.fraction = stage, fraction

    def work() -> None:
        mesh_path = path
        try:
            if path.suffix.lower() == ".zip":
                from ..scan.pipeline import scan_zip
                progress("scanning RGB-D frames", 0.05)
                result = scan_zip(path, folder / (path.stem + ".ply"), **(scan_options or {}))
                mesh_path = Path(result.mesh_path)
            progress("reading", 0.05)
            raw = load_mesh(str(mesh_path))
            mesh, graph, upright = prepare_upright(raw, str(mesh_path), nodes, progress=progress)
        except KinetreError as exc:
            job.failed(str(exc).replace(str(folder) + os.sep, ""))
            return
        except Exception as exc:  # a bug must still reach the page as a message, not a dead bar
            job.failed(f"{job.name}: could not prepare the mesh ({type(exc).__name__}: {exc})")
            return
        finally:
            shutil.rmtree(folder, ignore_errors=True)

        def swap() -> None:
            ready(mesh, graph, mesh_path.name if mesh_path != path else Path(job.name).name, upright, raw)
            job.done = True

        loop.call_soon_threadsafe(swap)

    threading.Thread(target=work, daemon=True).start()
