"""Run tests/physics/replay_take.ts (the page's physics modules, bundled for node by esbuild) on a take."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WEB = ROOT / "web"


def bundle(out: Path, entry: Path = Path(__file__).with_name("replay_take.ts")) -> Path:
    """The TypeScript entry and the web modules it imports as one node ES module."""
    esbuild = WEB / "node_modules" / ".bin" / "esbuild"
    assert esbuild.is_file(), "web/node_modules is missing: run `npm ci` in web/"
    subprocess.run([str(esbuild), str(entry), "--bundle", "--platform=node", "--format=esm", f"--outfile={out}",
                    "--log-level=warning"], check=True, cwd=WEB, timeout=120)
    return out


def node_replay(script: Path, mesh: Path, transforms: Path, fps: float, runs: int = 2, preset: str = "tower",
                placement: list[float] | None = None) -> dict:
    """{"frames", "runs": [{"knockedDown", "boxes", "steps", "states", ...}]} from `runs` fresh worlds."""
    config = {"mesh": str(mesh), "transforms": str(transforms), "fps": fps, "preset": preset, "runs": runs}
    if placement is not None:
        config["placement"] = placement
    out = subprocess.run(["node", str(script), json.dumps(config)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])
