"""Runs fuzz cases in a separate reader process (worker.py), so a native crash (a segmentation fault in a
compiled kernel, trimesh, Open3D) or a hang is reported as a failing case instead of ending the test run."""
from __future__ import annotations

import base64
import json
import os
import select
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
# A case that takes this much CPU time, or this long at all, is a hang (the slowest seed takes a few CPU
# seconds, a first Open3D import included). CPU time, not wall time, is what a loaded machine leaves alone.
CASE_CPU = 90.0
CASE_WALL = 1200.0


@dataclass(frozen=True)
class Outcome:
    status: str   # ok | refused | bug | crash | hang
    detail: str


class Worker:
    """One reader process, restarted after a crash or hang."""

    def __init__(self):
        self.proc: subprocess.Popen | None = None
        self.cases = 0
        self.log = None

    def _start(self) -> None:
        env = dict(os.environ)
        env["PYTHONFAULTHANDLER"] = "1"  # a crash's Python stack goes to stderr
        self.log = tempfile.TemporaryFile()  # a file, not a pipe: a chatty reader cannot fill it and stall
        self.proc = subprocess.Popen([sys.executable, str(HERE / "worker.py")], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=self.log, env=env)

    def run(self, reader: str, files: dict[str, bytes], main: str) -> Outcome:
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        self.cases += 1
        line = json.dumps({"reader": reader, "main": main,
                           "files": {k: base64.b64encode(v).decode() for k, v in files.items()}}) + "\n"
        try:
            self.proc.stdin.write(line.encode())
            self.proc.stdin.flush()
        except BrokenPipeError:
            return self._died()
        start_cpu, start = self._cpu(), time.monotonic()
        while not select.select([self.proc.stdout], [], [], 2.0)[0]:
            used = self._cpu() - start_cpu
            if self.proc.poll() is not None:
                return self._died()
            if used > CASE_CPU or time.monotonic() - start > CASE_WALL:
                self.stop()
                return Outcome("hang", f"no answer after {used:.0f} s of CPU time")
        answer = self.proc.stdout.readline()
        if not answer:
            return self._died()
        result = json.loads(answer)
        return Outcome(result["status"], result["detail"])

    def _cpu(self) -> float:
        """CPU seconds the reader process has used (user + system)."""
        try:
            fields = Path(f"/proc/{self.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            return 0.0
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def _died(self) -> Outcome:
        code = self.proc.wait()
        self.log.seek(0)
        stderr = self.log.read().decode(errors="replace")
        self.stop()
        what = f"signal {signal.Signals(-code).name}" if code < 0 else f"exit {code}"
        return Outcome("crash", f"reader process died ({what})\n{stderr[-3000:]}")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        if self.proc is not None:
            for stream in (self.proc.stdin, self.proc.stdout):
                stream.close()
            self.log.close()
        self.proc = None
