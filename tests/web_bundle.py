"""The page's TypeScript bundled by esbuild for node, so tests run the page's own code beside the Python."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

WEB_SRC = Path(__file__).resolve().parents[1] / "web" / "src"
ESBUILD = WEB_SRC.parent / "node_modules" / ".bin" / "esbuild"


def esbuild(entries, *options: str) -> None:
    """Bundle `entries` (paths relative to web/src) as ES modules; `options` say where (--outfile/--outdir)."""
    assert ESBUILD.exists(), "web/node_modules is missing: npm ci in web/ (make setup does)"
    subprocess.run([str(ESBUILD), *(str(WEB_SRC / e) for e in entries), "--bundle", "--format=esm",
                    "--log-level=warning", *options], check=True, timeout=120)


def run_node(runner: Path, bundle: Path, fixture: dict, *args: str):
    """What `node runner bundle args…` prints (JSON) when given `fixture` (JSON) on stdin."""
    out = subprocess.run(["node", str(runner), str(bundle), *args], input=json.dumps(fixture),
                         capture_output=True, text=True, timeout=120, check=True)
    return json.loads(out.stdout)


def bundled(folder: Path, entry: str) -> Path:
    """`entry` (relative to web/src) bundled into `folder` as one ES module; its path."""
    out = folder / (Path(entry).stem + ".mjs")
    esbuild([entry], f"--outfile={out}")
    return out
