"""A real nats-server (Debian package `nats-server`, installed by the Makefile) on 127.0.0.1 for tests and benchmarks.

Rooms "a" and "b" with their own tokens; each room's user may only touch `kinetre.<room>.>`.
"""
from __future__ import annotations

import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

from kinetre.studio.natsbus import server_config

ROOMS = {"a": "token-a-5f1c", "b": "token-b-93e0"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def nats_binary() -> str:
    """The nats-server executable; a missing one is an error, never a skip (`make setup` installs it)."""
    path = shutil.which("nats-server") or ("/usr/sbin/nats-server" if Path("/usr/sbin/nats-server").exists() else None)
    if path is None:
        raise RuntimeError("nats-server is not installed: apt-get install nats-server (the Makefile's APT_PACKAGES)")
    return path


class NatsServer:
    """start() / kill() (SIGKILL) / start() again on the same port; use as a context manager."""

    def __init__(self, rooms: dict[str, str] = ROOMS):
        self.port = free_port()
        self.folder = Path(tempfile.mkdtemp(prefix="kinetre-nats-"))
        self.config = self.folder / "nats.conf"
        self.config.write_text(server_config(rooms, self.port))
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"nats://127.0.0.1:{self.port}"

    def start(self, timeout: float = 10.0) -> "NatsServer":
        self.proc = subprocess.Popen([nats_binary(), "-c", str(self.config)], stdout=subprocess.DEVNULL,
                                     stderr=open(self.folder / "log.txt", "ab"))
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError("nats-server exited: " + (self.folder / "log.txt").read_text()[-1000:])
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=0.5):
                    return self
            except OSError:
                time.sleep(0.05)
        raise RuntimeError("nats-server did not start in time")

    def kill(self) -> None:
        """kill -9: no goodbye to the clients."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
            self.proc.wait(10)

    def __enter__(self) -> "NatsServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.kill()
        shutil.rmtree(self.folder, ignore_errors=True)
