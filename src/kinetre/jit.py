"""numba's `njit` and `prange` for Kinetre's kernels, with an on-disk cache that goes stale with the sources.

numba keys a cached kernel on its own file only. A kernel that calls or inlines a kernel of another module
(or freezes a constant imported from one) would run the old machine code after that other file changed,
e.g. after an upgrade in place. Importing `njit` from here registers a cache locator for the files of this
package: it keeps the location numba would choose (NUMBA_CACHE_DIR, the package's __pycache__, or the
user-wide cache) and adds to each kernel's source stamp one hash of every Kinetre file a kernel can depend
on: the modules that define kernels and, transitively, the Kinetre modules they import. Any change there makes
every kernel recompile once (numba then overwrites its stale index); a change elsewhere (the command line,
the studio) keeps the cache. The sources are read and hashed once per
process that loads kernels.

Without NUMBA_CACHE_DIR the kernels are cached in the per-user cache folder (`userdirs.user_cache_dir()`,
`numba` in it), not beside the sources: an installed package's folder is often read-only, and numba's own
fallback then would be a folder shared with every other numba program. So a kernel compiles once per user and
Kinetre version, not in every run.
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import re
from pathlib import Path

from numba import njit, prange
from numba.core import caching, config, event
from numba.core.compiler_lock import global_compiler_lock

from .compile_notice import compiling
from .userdirs import user_cache_dir

__all__ = ["njit", "prange", "slp_vectorizer", "sources_stamp", "kernel_cache_dir"]

PACKAGE = Path(__file__).resolve().parent
_IMPL = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # numba < 0.60: _CacheImpl

# `from .a.b import c`, `from .. import (x, y as z)` and `import kinetre.a.b`, at any indentation
_IMPORT = re.compile(rb"^[ \t]*(?:from[ \t]+(\.+)([\w.]*)[ \t]+import[ \t]+(?:\(([^)]*)\)|([\w ,\t]+))"
                     rb"|import[ \t]+kinetre\.([\w.]+))", re.MULTILINE)


@contextlib.contextmanager
def slp_vectorizer():
    """Kernels compiled (or loaded from the cache) inside get LLVM's SLP vectoriser.

    numba leaves it off (numba PR 8852: miscompilations with the LLVM of the time), so a loop body written
    as 4-lane arithmetic, the way a per-vertex kernel gets SIMD without gathers, stays scalar. numba reads
    the flag each time it builds a pass pipeline; holding its compiler lock keeps the change to the
    compilations made here. Call a kernel inside only for its first call per signature (the lock
    serialises every compilation in the process); the kernel's tests check its results.
    """
    with global_compiler_lock:
        before = config.SLP_VECTORIZE
        config.SLP_VECTORIZE = 1
        try:
            yield
        finally:
            config.SLP_VECTORIZE = before


@functools.cache
def sources_stamp(package: Path = PACKAGE) -> str:
    """Hash of the sources under `package` that its kernels can depend on (see the module docstring)."""
    sources = {}
    for folder, subfolders, files in os.walk(package):
        subfolders[:] = [d for d in subfolders if d not in ("__pycache__", "static")]  # the studio's build
        prefix = os.path.relpath(folder, package).replace(os.sep, "/") + "/"
        for file in files:
            if file.endswith(".py"):
                with open(os.path.join(folder, file), "rb") as fh:
                    sources[(prefix + file[:-3]).removeprefix("./")] = fh.read()
    todo = [name for name, text in sources.items() if b"njit" in text]  # the kernel modules
    used = set(todo)
    while todo:
        for dep in _imported(todo.pop(), sources):
            if dep not in used:
                used.add(dep)
                todo.append(dep)
    digest = hashlib.blake2b(digest_size=16)
    for name in sorted(used):
        digest.update(name.encode() + b"\0" + sources[name] + b"\0")
    return digest.hexdigest()


def _imported(name: str, sources: dict[str, bytes]) -> set[str]:
    """The package modules (keys of `sources`: "graph/weights", "graph/__init__") that module `name` imports."""
    package = name.split("/")[:-1]  # the package a relative import starts from, for a module or an __init__
    found = set()
    for dots, module, listed, names, absolute in _IMPORT.findall(sources[name]):
        names = listed or names
        if absolute:
            bases = [absolute.decode().split(".")]
        else:
            stem = package[:len(package) - len(dots) + 1] + (module.decode().split(".") if module else [])
            # `from .x import y`: y may be a submodule of x, or a name defined in x
            bases = [stem] + [stem + [n.split()[0]] for n in names.decode().split(",") if n.strip()]
        for candidate in bases:
            for key in ("/".join(candidate), "/".join(candidate + ["__init__"])):
                if key in sources and key != name:
                    found.add(key)
    return found


def _inside(path: str, package: Path = PACKAGE) -> bool:
    try:
        return Path(os.path.realpath(path)).is_relative_to(package)
    except (OSError, ValueError):
        return False


def kernel_cache_dir() -> Path:
    """Where Kinetre's compiled kernels are kept: NUMBA_CACHE_DIR when set, else the per-user cache folder."""
    return Path(config.CACHE_DIR) if config.CACHE_DIR else user_cache_dir() / "numba"


class UserCacheLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
    """numba's locator for NUMBA_CACHE_DIR, with `kernel_cache_dir()` in its place."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = os.path.join(kernel_cache_dir(), self.get_suitable_cache_subpath(py_file))

    def get_cache_path(self):
        return self._cache_path


class SourceSetLocator(caching._CacheLocator):
    """numba's own choice of cache locator for a Kinetre kernel, with `sources_stamp()` in its stamp."""

    def __init__(self, inner: caching._CacheLocator):
        self._inner = inner

    def ensure_cache_path(self):
        self._inner.ensure_cache_path()

    def get_cache_path(self):
        return self._inner.get_cache_path()

    def get_source_stamp(self):
        return self._inner.get_source_stamp(), sources_stamp()

    def get_disambiguator(self):
        return self._inner.get_disambiguator()

    @classmethod
    def from_function(cls, py_func, py_file):
        if not _inside(py_file):
            return None
        if not config.CACHE_DIR:
            inner = UserCacheLocator.from_function(py_func, py_file)  # None when the folder cannot be made
            if inner is not None:
                return cls(inner)
        for other in _IMPL._locator_classes:
            if other is not cls:
                inner = other.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
        return None


if SourceSetLocator not in _IMPL._locator_classes:
    _IMPL._locator_classes.insert(0, SourceSetLocator)


class CompileListener(event.Listener):
    """Tells `compile_notice` when a Kinetre kernel is compiled (numba sends the event on a cache miss only)."""

    def on_start(self, ev):
        func = getattr(ev.data.get("dispatcher"), "py_func", None)
        if getattr(func, "__module__", "").startswith(__package__ + "."):
            compiling()

    def on_end(self, ev):
        pass


if not any(isinstance(x, CompileListener) for x in event._registered.get("numba:compile", ())):
    event.register("numba:compile", CompileListener())
