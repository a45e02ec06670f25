"""The page's TypeScript bundled by esbuild for node, so tests run the page's own code beside the Python."""
from __future__ import annotations

import subprocess
from pathlib import Path

WEB_SRC = Path(__file__).resolve().parents[1] / "web" / "src"
ESBUILD = WEB_SRC.parent / "node_modules" / ".bin" / "esbuild"


def esbuild(entries, *options: str) -> None:
    """Bundle `entries` (paths relative to web/src) as ES modules; `options` say where (--outfile/--outdir)."""
    assert ESBUILD.exists(), "web/node_modules is missing: npm ci in web/ (make setup does)"
    subprocess.run([str(ESBUILD), *(str(WEB_SRC / e) for e in entries), "--bundle", "--format=esm",
                    "--log-level=warning", *options], check=True, timeout=120)
