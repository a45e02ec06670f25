"""Kinetre's kernels: `njit` and `prange` as numba's, with an on-disk cache that goes stale with the sources,
and numba itself loaded only when a kernel has no ahead-of-time compiled twin.

numba keys a cached kernel on its own file only. A kernel that calls or inlines a kernel of another module
(or freezes a constant imported from one) would run the old machine code after that other file changed,
e.g. after an upgrade in place. Loading numba from here registers a cache locator for the files of this
package: it keeps the location numba would choose (NUMBA_CACHE_DIR, the package's __pycache__, or the
user-wide cache) and adds to each kernel's source stamp one hash of every Kinetre file a kernel can depend
on: the modules that define kernels and, transitively, the Kinetre modules they import. Any change there makes
every kernel recompile once (numba then overwrites its stale index); a change elsewhere (the command line,
the studio) keeps the cache. The sources are read and hashed once per process that loads kernels.

Without NUMBA_CACHE_DIR the kernels are cached in the per-user cache folder (`userdirs.user_cache_dir()`,
`numba` in it), not beside the sources: an installed package's folder is often read-only, and numba's own
fallback then would be a folder shared with every other numba program. So a kernel compiles once per user and
Kinetre version, not in every run.

Even from its cache, numba costs a command about 0.3 s before the first kernel runs (its import, its typing
tables, each kernel's machine code linked in). So `kinetre kernels` (run by `make setup`) also compiles the
signatures a run uses ahead of time, with numba's AOT compiler, into one extension module in the same folder
(`compiled.py`), stamped like the cache. Until numba is needed, `njit` gives a `Kernel`: a call whose argument
types match a compiled signature runs that; any other call loads numba, after which every kernel is numba's
own dispatcher (swapped into the modules that hold it, so kernels calling kernels compile as before).
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import json
import os
import re
import sys
import threading
from pathlib import Path

import numpy as np

from .compile_notice import compiling
from .userdirs import user_cache_dir

__all__ = ["njit", "intrinsic", "prange", "Kernel", "load_numba", "slp_vectorizer", "sources_stamp",
           "kernel_cache_dir", "compiled_dir", "signature_matcher", "COMPILED_TABLE"]

PACKAGE = Path(__file__).resolve().parent

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
    load_numba()
    from numba.core import config
    from numba.core.compiler_lock import global_compiler_lock
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
    folder = os.environ.get("NUMBA_CACHE_DIR")  # what numba's config reads at its import
    return Path(folder) if folder else user_cache_dir() / "numba"


# ---------------------------------------------------------------------------------------------------------
# Kernels before numba: the ahead-of-time compiled twins, else numba's dispatcher

COMPILED_MODULE = "kinetre_compiled_kernels"
COMPILED_TABLE = "kernels.json"  # beside the module: its file and, per exported symbol, kernel and signature
_LOCK = threading.RLock()
_STATE: dict = {"numba": None, "compiled": None}
_MADE: list = []  # Kernels and intrinsics made before numba was loaded


def compiled_dir() -> Path:
    """The folder of the compiled kernels for these sources, this numpy and this Python (the module links
    against both); `kinetre kernels` writes it, and a stale one is never read (its name would differ)."""
    digest = hashlib.blake2b(digest_size=10)
    for part in (sources_stamp(), np.__version__, sys.version, sys.platform):
        digest.update(part.encode() + b"\0")
    return kernel_cache_dir() / "compiled" / digest.hexdigest()


def signature_matcher(keys: tuple):
    """A test `match(args) -> bool`: whether numba would type the call's arguments `args` as `keys`, the
    argument types of one compiled signature (`compiled.type_key`'s keys: an array's dtype, dimensions,
    layout and read-only flag; a scalar's type; a tuple's members; None). Generated as one expression, so a
    45-argument solve step is matched in a few microseconds."""
    names = [f"a{i}" for i in range(len(keys))]
    test = " and ".join(_test(key, name) for key, name in zip(keys, names)) or "True"
    unpack = f"    {', '.join(names)}, = args\n" if names else ""
    code = f"def match(args):\n    if len(args) != {len(keys)}:\n        return False\n{unpack}    return {test}\n"
    space = {"ndarray": np.ndarray, "np": np, "masked": np.ma.MaskedArray}
    space.update({f"dtype_{name}": np.dtype(name) for name in _array_dtypes(keys)})
    exec(code, space)
    return space["match"]


_SCALARS = {"float64": ("float", "np.float64"), "bool": ("bool", "np.bool_"), "int64": ("int", "np.int64")}
_INT64 = (-2 ** 63, 2 ** 63 - 1)


def _test(key, name: str) -> str:
    """The expression testing argument `name` against a type key."""
    if key == "none":
        return f"{name} is None"
    if isinstance(key, str):  # a scalar: numba types Python's int, float and bool as int64, float64, bool
        python, numpy = _SCALARS.get(key, (None, f"np.{key}"))
        exact = f"type({name}) is {numpy}"
        if python is None:
            return exact
        inside = f" and {_INT64[0]} <= {name} <= {_INT64[1]}" if python == "int" else ""
        return f"((type({name}) is {python}{inside}) or {exact})"
    if key[0] == "tuple":
        members = [_test(k, f"{name}[{i}]") for i, k in enumerate(key[1:])]
        return f"(type({name}) is tuple and len({name}) == {len(members)}" + "".join(f" and {m}" for m in members) + ")"
    _, dtype, ndim, layout, readonly = key
    layout_test = {"C": "f.c_contiguous", "F": "not f.c_contiguous and f.f_contiguous",
                   "A": "not f.c_contiguous and not f.f_contiguous"}[layout]
    # an ndarray subclass is typed as an array too (numba's typeof dispatches on ndarray)
    return (f"(isinstance({name}, ndarray) and {name}.dtype == dtype_{dtype} and {name}.dtype.isnative and "
            f"{name}.ndim == {ndim} and {'not ' if readonly else ''}(f := {name}.flags).writeable and {layout_test} "
            f"and not isinstance({name}, masked))")


def _array_dtypes(keys) -> set[str]:
    found = set()
    for key in keys:
        if isinstance(key, tuple):
            found |= {key[1]} if key[0] == "array" else _array_dtypes(key[1:])
    return found


def _as_key(item):
    """A key as read back from JSON (lists) → tuples."""
    return tuple(_as_key(x) for x in item) if isinstance(item, list) else item


def _compiled_kernels() -> dict:
    """{(module, qualname): [(signature matcher, compiled function)]} from `compiled_dir()`, {} when there is none
    (or it cannot be loaded: then every call goes to numba, as without it)."""
    with _LOCK:
        table = _STATE["compiled"]
        if table is None:
            table = _STATE["compiled"] = _load_compiled(compiled_dir())
        return table


def _load_compiled(folder: Path) -> dict:
    try:
        listing = json.loads((folder / COMPILED_TABLE).read_text())
        spec = importlib.util.spec_from_file_location(COMPILED_MODULE, folder / listing["file"])
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        table: dict = {}
        for module_name, qualname, key, symbol in listing["kernels"]:
            table.setdefault((module_name, qualname), []).append((signature_matcher(_as_key(key)),
                                                                   getattr(module, symbol)))
        return table
    except (OSError, ValueError, KeyError, TypeError, ImportError, AttributeError):
        return {}


class Kernel:
    """`njit`'s kernel until numba is loaded: a call runs the compiled twin of its argument types, if
    `kinetre kernels` made one, else numba's dispatcher (made on first need; that loads numba). Attributes
    other than these are the dispatcher's (`stats`, `signatures`, ...)."""

    def __init__(self, py_func, options: dict):
        self._dispatcher = None
        self._twins = None
        self.py_func, self.options = py_func, options
        functools.update_wrapper(self, py_func)

    def __call__(self, *args, **kwargs):
        twins = self._twins
        if twins is None:
            twins = self._twins = _compiled_kernels().get((self.py_func.__module__, self.py_func.__qualname__), ())
        if not kwargs:
            for match, twin in twins:
                if match(args):
                    return twin(*args)
        return self.dispatcher(*args, **kwargs)

    @property
    def dispatcher(self):
        """numba's dispatcher for this kernel (loads numba)."""
        if self._dispatcher is None:
            load_numba()
        return self._dispatcher

    def realise(self, numba) -> None:
        self._dispatcher = numba.njit(**self.options)(self.py_func)

    @property
    def real(self):
        return self._dispatcher

    def __getattr__(self, name):
        if name.startswith("__") or name in ("_dispatcher", "_twins"):
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __repr__(self):
        return f"<kinetre kernel {self.py_func.__module__}.{self.py_func.__qualname__}>"


class Intrinsic:
    """`intrinsic`'s object until numba is loaded: numba's `intrinsic` of the same definition after."""

    def __init__(self, definition):
        self.definition, self.real = definition, None
        functools.update_wrapper(self, definition)

    def realise(self, numba) -> None:
        from numba.extending import intrinsic as numba_intrinsic
        self.real = numba_intrinsic(self.definition)

    def __call__(self, *args):
        raise TypeError(f"{self.definition.__qualname__} is an intrinsic: it can be called inside a kernel only")


def njit(*args, **options):
    """numba's `njit` (options only, as `@njit` or `@njit(cache=True, ...)`), a `Kernel` until numba is
    loaded."""
    def decorate(py_func):
        with _LOCK:
            numba = _STATE["numba"]
            if numba is not None:
                return numba.njit(**options)(py_func)
            kernel = Kernel(py_func, options)
            _MADE.append(kernel)
            return kernel
    if len(args) == 1 and callable(args[0]) and not options:
        return decorate(args[0])
    if args:
        raise TypeError("kinetre.jit.njit takes options only, not signatures")
    return decorate


def intrinsic(definition):
    """numba's `intrinsic`, made when numba is loaded (the definition runs only inside numba's typing)."""
    with _LOCK:
        numba = _STATE["numba"]
        if numba is not None:
            from numba.extending import intrinsic as numba_intrinsic
            return numba_intrinsic(definition)
        made = Intrinsic(definition)
        _MADE.append(made)
        return made


def __getattr__(name):
    if name == "prange":  # only parallel kernels need it; it is numba's own object
        return load_numba().prange
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def load_numba():
    """Import numba with Kinetre's cache locator and compile notice, make the dispatchers of the kernels
    made so far and put them in place of their `Kernel`s in Kinetre's modules (numba resolves a kernel's
    callees from its globals when it compiles it; a `Kernel` held elsewhere calls its dispatcher). Returns
    the numba module."""
    with _LOCK:
        if _STATE["numba"] is not None:
            return _STATE["numba"]
        import numba
        _register_cache_locator()
        _register_compile_listener()
        for made in _MADE:
            made.realise(numba)
        swap = {id(made): made.real for made in _MADE}
        for module_name, module in list(sys.modules.items()):
            if module_name.partition(".")[0] != __package__ or module is None:
                continue
            space = vars(module)
            for name, value in list(space.items()):
                if type(value) in (Kernel, Intrinsic) and id(value) in swap:
                    space[name] = swap[id(value)]
        _MADE.clear()
        _STATE["numba"] = numba
        return numba


def _register_cache_locator() -> None:
    from numba.core import caching, config
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # numba < 0.60: _CacheImpl
    if any(getattr(c, "__qualname__", "") == "SourceSetLocator" for c in impl._locator_classes):
        return

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

        def __init__(self, inner):
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
            for other in impl._locator_classes:
                if other is not cls:
                    inner = other.from_function(py_func, py_file)
                    if inner is not None:
                        return cls(inner)
            return None

    impl._locator_classes.insert(0, SourceSetLocator)


def _register_compile_listener() -> None:
    from numba.core import event

    class CompileListener(event.Listener):
        """Tells `compile_notice` when a Kinetre kernel is compiled (numba sends the event on a cache miss
        only)."""

        def on_start(self, ev):
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            if getattr(func, "__module__", "").startswith(__package__ + "."):
                compiling()

        def on_end(self, ev):
            pass

    if not any(type(x).__qualname__.endswith("CompileListener") for x in event._registered.get("numba:compile", ())):
        event.register("numba:compile", CompileListener())
