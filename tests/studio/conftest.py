"""A studio server in a subprocess on 127.0.0.1 (so clients in the test process do not share its GIL)."""
from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import pytest

ROOT = Path(__file__).parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(mesh: str | None = None, nodes: int = 128, sample_motion: bool = False, timeout: float = 600,
                 **options):
    """(process, base URL) of a running studio; the caller terminates the process. `timeout` is generous: a
    loaded machine compiling the kernels afresh (an empty cache) takes minutes to start one.

    `options` go to run_studio (nats=, room=, token=, remote_scene=).
    """
    port = free_port()
    code = (f"from kinetre.studio.app import run_studio; run_studio({mesh!r}, '127.0.0.1', {port}, False, "
            f"nodes={nodes}, sample_motion={sample_motion}, **{options!r})")
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    log = tempfile.TemporaryFile()  # not a pipe: nobody reads it while the server runs, so it must not fill
    proc = subprocess.Popen([sys.executable, "-c", code], env=env, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            log.seek(0)
            raise RuntimeError(f"studio exited: {log.read().decode()[-2000:]}")
        try:
            if httpx.get(url + "/api/state", params={"token": options.get("token") or ""},
                         timeout=2).status_code == 200:
                return proc, url
        except httpx.HTTPError:
            time.sleep(0.3)
    proc.kill()
    proc.wait(10)
    log.seek(0)
    raise RuntimeError(f"studio did not start in {timeout:.0f} s: {log.read().decode()[-2000:]}")


@pytest.fixture(scope="module")
def studio():
    proc, url = start_server()
    yield url
    proc.terminate()
    proc.wait(10)


@pytest.fixture(scope="session")
def walk(data_dir):
    """The CMU walk as Kinect-20 skeletons (metres, +Y up), 30 fps, as a capture client sends them: joint
    positions only (the wire carries no bone frames, so an in-process reference must not use them either)."""
    from dataclasses import replace

    from kinetre.motion.bvh import load_bvh
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    return [replace(take.frame(i), bone_frames=None) for i in range(0, len(take), 4)]
