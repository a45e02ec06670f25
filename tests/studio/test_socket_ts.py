"""The page's socket (web/src/net/StudioSocket.ts, run under node): after a dropped connection it comes back
with the resume token of its welcome, so the studio gives it back its user; closing on purpose says so."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

from web_bundle import esbuild

RUNNER = Path(__file__).resolve().parent / "node" / "socket_ts.mjs"


def test_the_page_reconnects_as_the_same_client_and_closes_with_a_code(tmp_path):
    bundle = tmp_path / "socket.mjs"
    esbuild(["net/StudioSocket.ts"], f"--outfile={bundle}")
    out = json.loads(subprocess.run(["node", str(RUNNER), str(bundle)], capture_output=True, text=True,
                                    timeout=120, check=True).stdout)
    assert out["urls"] == ["ws://studio/ws?token=t", "ws://studio/ws?token=t&resume=c7.s3cret-_x"]
    assert out["closeCode"] == 1000  # the server forgets a page that leaves on purpose at once
    assert out["client"] == "c7"
