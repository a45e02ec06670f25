"""The page's live motion meter (web/src/app/QualityMeter.ts in the status line, run under node): each user's
figures from the server's LiveMeter in a few words."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from web_bundle import esbuild

RUNNER = Path(__file__).resolve().parent / "node" / "status_ts.mjs"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    out = tmp_path_factory.mktemp("ts") / "status.mjs"
    esbuild(["app/StatusLine.ts"], f"--outfile={out}")
    return out


def line(bundle, users) -> str:
    facts = {"connected": True, "client": "me", "refused": "", "sceneLost": False, "camera": True,
             "trackingLost": False, "trackedJoints": 20, "fps": 30,
             "state": {"mesh": {"name": "spot", "nodes": 256}, "meshes": [], "users": users, "solve_ms": None}}
    out = subprocess.run(["node", str(RUNNER), str(bundle)], input=json.dumps(facts), capture_output=True,
                         text=True, timeout=120, check=True)
    return out.stdout


def test_each_user_has_a_motion_meter(bundle):
    quality = {"frames": 90, "jitter_tracked": 60.0, "jitter": 27.0, "lag_ms": 2.4, "held": 0.8, "stray_cm": 0.31}
    users = [{"client": "me", "possessing": True, "subset": None, "frames": 90, "attached": [], "quality": quality},
             {"client": "p2", "possessing": False, "subset": None, "frames": 90, "attached": [],
              "quality": {**quality, "held": 0.0, "jitter": 12.0}},
             {"client": "old", "possessing": False, "subset": None, "frames": 3, "attached": []}]
    text = line(bundle, users)
    assert "your motion: jitter −55 %, feet held 80 %, slide 0.3 cm, lag 2 ms" in text
    assert "p2's motion: jitter −80 %, feet held 0 %, lag 2 ms" in text
    assert "old's motion" not in text  # a server without the meter: nothing shown


def test_the_meter_says_what_cleaning_applies(bundle):
    quality = {"frames": 90, "jitter_tracked": 4.2, "jitter": 4.2, "lag_ms": 0.0, "held": 0.5, "stray_cm": 0.8}
    users = [{"client": "me", "possessing": True, "subset": None, "frames": 90, "attached": [], "quality": quality,
              "cleaning": []},
             {"client": "sample", "possessing": False, "subset": None, "frames": 90, "attached": [],
              "quality": quality, "cleaning": ["contact"]}]
    text = line(bundle, users)
    assert "your motion: jitter 4.2 m/s², as tracked" in text          # --raw, or mocap as sent
    assert "sample's motion: jitter 4.2 m/s², feet held 50 %, slide 0.8 cm ·" in text  # --contact: no lag
