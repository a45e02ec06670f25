"""A fresh virtualenv holding the built Kinetre wheel and, beside it, only what the wheel says it needs.

Installing numpy, scipy, numba, Open3D … from PyPI in every test run would take minutes and a network. The
project's venv already holds the exact versions `make setup` installed, so the fresh venv gets them by
symbolic links instead: for the closure of the wheel's own `Requires-Dist` (no extras but the ones it names,
markers evaluated), each distribution's top-level files (its packages, its .libs, its .dist-info) are linked
into the fresh venv's site-packages. pip then installs the wheel with `--no-index`: it can satisfy a
dependency only from those links, so a dependency the wheel forgets to declare is missing in the new venv
(pip or the first import fails), and the project's own Kinetre (an editable install of src/) is never on
its path. The venv is made by the base interpreter, and the test runs it with its cwd outside the repository
and no PYTHONPATH.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from email.parser import Parser
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[2]


def build_wheel(out: Path) -> Path:
    """The wheel `make dist` builds, from a copy of this checkout's sources (so nothing a build left in the
    checkout gets in) into `out`; it needs the studio page built (`make web`)."""
    assert (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file(), "build the page: make web"
    tree = out / "tree"
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        tree.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / name, tree / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "*.nbi", "*.nbc")
    for name in ("licenses", "src"):
        shutil.copytree(ROOT / name, tree / name, ignore=ignore)
    pip = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(out), str(tree)],
                         capture_output=True, text=True, timeout=600)
    assert pip.returncode == 0, pip.stderr
    (wheel,) = out.glob("kinetre-*-py3-none-any.whl")
    return wheel


def wheel_metadata(wheel: Path):
    with zipfile.ZipFile(wheel) as z:
        name = next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))
        return Parser().parsestr(z.read(name).decode())


def closure(requirements: list[str]) -> dict[str, metadata.Distribution]:
    """The installed distributions `requirements` need, transitively (each with the extras asked of it)."""
    found: dict[str, metadata.Distribution] = {}
    todo = [(Requirement(r), "") for r in requirements]
    seen = set()
    while todo:
        req, extra = todo.pop()
        if req.marker is not None and not req.marker.evaluate({"extra": extra}):
            continue
        key = (canonicalize_name(req.name), tuple(sorted(req.extras)))
        if key in seen:
            continue
        seen.add(key)
        dist = metadata.distribution(req.name)
        found[canonicalize_name(req.name)] = dist
        for sub in dist.requires or []:
            sub_req = Requirement(sub)
            for want in [""] + sorted(req.extras):
                todo.append((sub_req, want))
    return found


def fresh_venv(where: Path, wheel: Path) -> Path:
    """A venv at `where` with `wheel` installed by pip; returns its bin folder."""
    base = getattr(sys, "_base_executable", sys.executable)
    subprocess.run([base, "-m", "venv", "--without-pip", str(where)], check=True, timeout=120, env=clean_env())
    purelib = Path(subprocess.run([str(where / "bin" / "python"), "-c",
                                   "import sysconfig; print(sysconfig.get_path('purelib'))"],
                                  check=True, capture_output=True, text=True, env=clean_env()).stdout.strip())
    ours = Path(sysconfig.get_path("purelib"))
    requires = wheel_metadata(wheel).get_all("Requires-Dist") or []
    for dist in closure(requires).values():
        # its packages, .libs and .dist-info (RECORD lists itself), never a shared __pycache__
        tops = {Path(str(f)).parts[0] for f in dist.files or () if not str(f).startswith("..")} - {"__pycache__"}
        for top in tops:
            src = ours / top
            if (src.exists() or src.is_symlink()) and not (purelib / top).exists():
                os.symlink(src, purelib / top)
    # the project venv's pip, pointed at the new interpreter: no ensurepip, no network (--no-index)
    pip = subprocess.run([sys.executable, "-m", "pip", "--python", str(where / "bin" / "python"), "install", "-q",
                          "--no-index", str(wheel)], capture_output=True, text=True, timeout=600, env=clean_env())
    assert pip.returncode == 0, pip.stderr
    return where / "bin"


def clean_env(**extra: str) -> dict[str, str]:
    """This process's environment without anything pointing at the checkout."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "NUMBA_CACHE_DIR", "PYTHONHOME")}
    env.update(extra)
    return env
