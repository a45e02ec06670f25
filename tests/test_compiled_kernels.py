"""Kernels compiled ahead of time (kinetre.compiled) run without numba, give numba's results to the bit, and
hand any call they were not compiled for to numba."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from importlib import resources

import numpy as np
import pytest

from kinetre.jit import compiled_dir, signature_matcher

SPOT = resources.files("kinetre") / "data" / "spot.obj"
WALK = resources.files("kinetre") / "data" / "cmu_12_01_walk.bvh"


def _values():
    base = np.arange(24, dtype=np.float64).reshape(4, 6)
    readonly = base.copy()
    readonly.flags.writeable = False
    return [base, base.T, base[:, ::2], base[0], readonly, base.astype(np.float32), base.astype(np.int32),
            np.zeros(3, np.uint8), np.zeros((2, 2), bool), np.zeros((2, 2, 2), np.complex128), np.zeros(0, np.int64),
            1.5, 3, -2 ** 40, True, None, np.float32(2.0), np.int64(7), np.bool_(False),
            (base, 2), (base[0], np.zeros(2, np.int32), (1.0, None))]


def test_a_call_matches_a_compiled_signature_exactly_when_numba_would_type_it_so():
    from numba import typeof

    from kinetre.compiled import type_key
    values = _values()
    keys = [type_key(typeof(v)) for v in values]
    assert None not in keys and len(set(keys)) == 18  # Python's and numpy's scalars of one type share a key
    # what no compiled kernel takes: numba's own type for it has no key, and no compiled signature matches it
    others = [[1.0, 2.0], "text", np.zeros(2, dtype=">f8"), np.zeros(2, dtype=[("a", "f8")]), 2 ** 70,
              np.ma.masked_array(np.zeros(3))]
    for key, value in zip(keys, values):
        match = signature_matcher((key,))
        assert [match((other,)) for other in values] == [k == key for k in keys], value
        assert not any(match((other,)) for other in others)
        assert not match(()) and not match((value, value))
    pair = signature_matcher((keys[0], keys[11]))
    assert pair((values[0], values[11])) and not pair((values[11], values[0]))


PROBE = """
import json, sys
import numpy as np
from kinetre import jit
from kinetre.graph import weights
points = np.random.default_rng(0).normal(size=(50, 3))
if sys.argv[1] == "build":
    jit.load_numba()
    weights._bounds(points)
    from kinetre.compiled import export_compiled, used_signatures
    folder, count = export_compiled([s for s in used_signatures() if s[1] == "_bounds"])
    print(json.dumps({"count": count}))
else:
    lo, hi = weights._bounds(points)
    compiled_only = "numba" not in sys.modules
    lo32, hi32 = weights._bounds(points.astype(np.float32))  # not compiled for float32: numba's
    print(json.dumps({"exact": bool((lo == points.min(0)).all() and (hi == points.max(0)).all()),
                      "exact32": bool((lo32 == points.astype(np.float32).min(0)).all()),
                      "compiled_only": compiled_only, "numba_after": "numba" in sys.modules,
                      "swapped": type(weights._bounds).__name__}))
"""


def test_a_compiled_kernel_runs_without_numba_and_other_signatures_go_to_numba(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "kernels"))

    def run(mode: str) -> dict:
        done = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True,
                              timeout=600)
        assert done.returncode == 0, done.stderr
        return json.loads(done.stdout.strip().splitlines()[-1])

    assert run("build") == {"count": 1}
    found = run("call")
    assert found == {"exact": True, "exact32": True, "compiled_only": True, "numba_after": True,
                     "swapped": "CPUDispatcher"}


ANIMATE = """
import hashlib, json, sys
from kinetre import jit
if sys.argv[1] == "numba":
    jit.load_numba()
from kinetre.cli.main import main
main(["animate", sys.argv[2], "--motion", sys.argv[3], "-o", sys.argv[4], "--max-frames", "6", "-q", "--no-cache"])
print(json.dumps({"numba": "numba" in sys.modules}))
"""


def test_make_setup_compiles_what_animate_uses_and_it_writes_numbas_bytes(tmp_path):
    if not compiled_dir().is_dir():
        pytest.skip("no compiled kernels for these sources: `make setup` (or `kinetre kernels`) compiles them")
    out = {}
    for mode in ("compiled", "numba"):
        out[mode] = tmp_path / f"{mode}.glb"
        done = subprocess.run([sys.executable, "-c", ANIMATE, mode, str(SPOT), str(WALK), str(out[mode])],
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        assert json.loads(done.stdout.strip().splitlines()[-1]) == {"numba": mode == "numba"}
    assert out["compiled"].read_bytes() == out["numba"].read_bytes()
