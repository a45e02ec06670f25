"""Run one of the browser drivers (tests/e2e/driver*.mjs) and read back its result.

Each driver takes its configuration as one JSON argument and prints its result as the last line of
stdout: {"ok": bool, "error": ..., "steps": [...], ...}.
"""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def run_driver(script: str, config: dict, timeout: float) -> dict:
    """The result of `node tests/e2e/<script> <config>`, asserted ok (the error, steps and stderr say why not)."""
    out = subprocess.run(["node", str(HERE / script), json.dumps(config)], capture_output=True, text=True,
                         timeout=timeout, cwd=ROOT)
    lines = out.stdout.strip().splitlines()
    assert lines, f"{script} printed nothing: {out.stderr[-2000:]}"
    result = json.loads(lines[-1])
    assert result["ok"], (result.get("error", "") + json.dumps(result.get("steps", []))[:2000]
                          + out.stderr[-1000:])
    return result
