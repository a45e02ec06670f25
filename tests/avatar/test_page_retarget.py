"""The studio page retargets in TypeScript (web/src/avatar/retarget.ts): on one fixture (a real walk with
tracking loss, each humanoid's plan from the server) it gives the Python retargeter's numbers."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from kinetre.avatar.retarget import RetargetState, retarget
from kinetre.skeleton.models import KINECT20

from avatar.conftest import HUMANOIDS
from web_bundle import esbuild

RUNNER = Path(__file__).resolve().parent / "node" / "retarget_ts.mjs"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    out = tmp_path_factory.mktemp("ts") / "retarget.mjs"
    esbuild(["avatar/retarget.ts"], f"--outfile={out}")
    return out


@pytest.mark.parametrize("name", HUMANOIDS)
def test_typescript_and_python_retarget_agree(bundle, rigged, walk, name):
    avatar, _, plan = rigged[name]
    pos, tracked = walk.positions[:30].copy(), walk.tracked[:30].copy()
    rng = np.random.default_rng(1)
    lost = rng.random(tracked.shape) < 0.15
    lost[0] = False
    lost[12:14] = True
    pos[lost] = np.nan
    tracked[lost] = False
    fixture = {"plan": plan.to_json(), "tracked": tracked.tolist(),
               "positions": [[None if not ok else p.tolist() for p, ok in zip(f, t)] for f, t in zip(pos, tracked)]}
    out = subprocess.run(["node", str(RUNNER), str(bundle)], input=json.dumps(fixture), capture_output=True, text=True,
                         timeout=120, check=True)
    page = json.loads(out.stdout)
    state = RetargetState()
    ours = [retarget(plan, pos[t:t + 1], tracked[t:t + 1], state) for t in range(len(pos))]
    size = np.ptp(avatar.bind_positions)
    np.testing.assert_allclose(np.array(page["world"]), np.stack([m.world[0] for m in ours]), atol=1e-9 * size)
    np.testing.assert_allclose(np.array(page["local"]), np.stack([m.local[0] for m in ours]), atol=1e-9 * size)
    assert len(KINECT20.joints) == len(fixture["positions"][0])
