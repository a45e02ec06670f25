"""A command-line run leaves the objects still alive frozen (so the interpreter's shutdown collections skip
them); `main(argv)` called in-process, as the tests and other programs do, leaves the collector alone."""
from __future__ import annotations

import gc
import subprocess
import sys

from kinetre.cli import main

PROBE = ("import gc, sys\nfrom kinetre.cli import main\nsys.argv = ['kinetre', 'info', sys.argv[1]]\n"
         "before = gc.get_freeze_count()\ncode = main()\nprint(code, before, gc.get_freeze_count() > before)")


def test_command_line_run_freezes_in_process_call_does_not(data_dir, capsys):
    spot = data_dir / "meshes" / "spot.obj"
    proc = subprocess.run([sys.executable, "-c", PROBE, str(spot)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "0 0 True"
    before = gc.get_freeze_count()
    assert main(["info", str(spot)]) == 0
    assert gc.get_freeze_count() == before and gc.isenabled()
    assert "3225 vertices" in capsys.readouterr().out
