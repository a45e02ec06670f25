"""The studio panel's joint-map entry in a real browser (tests/e2e/driver_rigs.mjs): upload, show, clear."""
from __future__ import annotations

import json
from pathlib import Path

from e2e.node_driver import run_driver
from studio.conftest import start_server

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def test_joint_map_upload_shows_and_clears(tmp_path):
    assert (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file(), "run `make web` first"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"sources": [{"keep": "legs", "ofset": [0, 0, 1]}]}))
    proc, url = start_server(nodes=64, sample_motion=False)
    try:
        config = {"url": url, "map": str(ROOT / "examples" / "maps" / "two-people-horse.json"), "bad": str(bad),
                  "artifacts": str(HERE / "artifacts")}
        result = run_driver("driver_rigs.mjs", config, 300)
    finally:
        proc.terminate()
        proc.wait(60)
    assert result["errors"] == []
    assert "bad.json: sources[0]: unknown key(s) ofset" in result["badMessage"]
    assert result["shown"] == "two-people-horse.json: 2 sources" and result["clearVisible"]
    assert result["server"] == {"name": "two-people-horse.json", "sources": 2}
    assert result["afterClear"] is None
