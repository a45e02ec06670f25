"""numba's on-disk cache of Kinetre's kernels goes stale with any kernel module (kinetre.jit), not only the
kernel's own file: after a helper module changes in place, the kernel that inlines it recompiles."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import kinetre

HELPER = "from .jit import njit\n\n\n@njit(cache=True)\ndef offset(x):\n    return x + {value}\n"
KERNEL = ("from .jit import njit\nfrom ._probe_helper import offset\n\n\n"
          "@njit(cache=True)\ndef kernel(x):\n    return 2 * offset(x)\n")
RUN = ("from kinetre._probe_kernel import kernel\nvalue = kernel(1.0)\nstats = kernel.stats\n"
       "print(value, sum(stats.cache_hits.values()), sum(stats.cache_misses.values()))")


@pytest.mark.slow
def test_kernel_recompiles_when_a_module_it_calls_changes(tmp_path):
    package = tmp_path / "src" / "kinetre"
    shutil.copytree(Path(kinetre.__file__).parent, package, ignore=shutil.ignore_patterns("__pycache__"))
    (package / "_probe_kernel.py").write_text(KERNEL)
    helper = package / "_probe_helper.py"
    env = dict(os.environ, PYTHONPATH=str(tmp_path / "src"), NUMBA_CACHE_DIR=str(tmp_path / "cache"))

    def run() -> tuple[float, int, int]:
        proc = subprocess.run([sys.executable, "-c", RUN], env=env, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        value, hits, misses = proc.stdout.split()
        return float(value), int(hits), int(misses)

    helper.write_text(HELPER.format(value=1))
    assert run() == (4.0, 0, 1)  # compiled and saved
    assert run() == (4.0, 1, 0)  # loaded from the cache
    helper.write_text(HELPER.format(value=10))  # the kernel's own file is unchanged
    assert run() == (22.0, 0, 1)  # numba alone would load the stale machine code and print 4.0
    assert run() == (22.0, 1, 0)
    (package / "animation.py").write_text((package / "animation.py").read_text() + "\n# an edit outside the kernels\n")
    assert run() == (22.0, 1, 0)


# njit (or jit, prange) taken from numba itself, in any import form
NUMBA_NJIT = re.compile(r"from numba[\w.]* import (?:\([^)]*|[^\n]*)\b(?:njit|jit|prange)\b|\bnumba\.(?:njit|jit)\b")


def test_every_kernel_module_uses_the_stamped_njit():
    # a module that took njit from numba itself would be cached on its own file only; other numba imports
    # (types, an intrinsic for live_stop's clock) are fine
    root = Path(kinetre.__file__).parent
    for path in root.rglob("*.py"):
        text = path.read_text()
        if path.name != "jit.py" and "njit" in text:
            assert not NUMBA_NJIT.search(text), path
            assert re.search(r"^from (?:\.+|kinetre\.)jit import [^\n]*\bnjit\b", text, re.MULTILINE), path
    for bad in ("from numba import njit", "from numba import types, njit", "from numba import (\n    njit,\n)",
                "import numba\nf = numba.njit(g)", "from numba.core.decorators import jit"):
        assert NUMBA_NJIT.search(bad), bad
    assert not NUMBA_NJIT.search("from numba import types\nfrom numba.extending import intrinsic\n")


def test_the_stamp_follows_relative_and_absolute_imports():
    from kinetre.jit import _imported
    sources = {"a/__init__": b"from . import (\n    b,\n    c as d,\n)\nfrom .e import f\n",
               "a/b": b"def g():\n    import kinetre.g\n", "a/c": b"", "a/e": b"from ..h import x\n", "g": b"",
               "h/__init__": b"", "e/f": b""}
    assert _imported("a/__init__", sources) == {"a/b", "a/c", "a/e"}
    assert _imported("a/b", sources) == {"g"}
    assert _imported("a/e", sources) == {"h/__init__"}


def test_slp_vectorizer_is_scoped_to_its_block():
    from numba.core import config

    from kinetre.jit import slp_vectorizer
    before = config.SLP_VECTORIZE
    with slp_vectorizer():
        assert config.SLP_VECTORIZE == 1
    assert config.SLP_VECTORIZE == before
    with pytest.raises(RuntimeError), slp_vectorizer():
        raise RuntimeError("a failed compilation")
    assert config.SLP_VECTORIZE == before
