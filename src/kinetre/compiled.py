"""Kinetre's kernels compiled ahead of time: every signature a run has used, exported with numba's AOT
compiler (`numba.pycc`) into one extension module, which `kinetre.jit` then loads without numba.

numba costs a command about 0.3 s before its first kernel runs, even from its cache: its import, its typing
tables, and each kernel's machine code linked into its JIT. The extension module is a plain shared library:
importing it costs a millisecond. It is written to `jit.compiled_dir()`, named by the same stamp as numba's
cache (and by numpy's and Python's versions), so a change to any kernel's sources is never served stale.

Each export is a thin entry calling the kernel's own dispatcher, so the kernel keeps its options (fastmath,
error model, inlining) and its callees; an entry of a `nogil` kernel releases the GIL, as its dispatcher does.
Parallel kernels are left to numba (the AOT compiler has no threading layer).
"""
from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import warnings
from pathlib import Path

from .jit import COMPILED_MODULE, COMPILED_TABLE, compiled_dir, load_numba

__all__ = ["type_key", "used_signatures", "export_compiled"]


def type_key(nbtype):
    """The key of numba type `nbtype` as an argument of a compiled signature (`jit.signature_matcher` tests a
    call against such keys), or None for a type the compiled kernels do not take."""
    from numba.core import types
    if isinstance(nbtype, types.Array):
        if not isinstance(nbtype.dtype, (types.Boolean, types.Integer, types.Float, types.Complex)) \
                or not nbtype.aligned:
            return None
        return ("array", str(nbtype.dtype), nbtype.ndim, nbtype.layout, not nbtype.mutable)
    if isinstance(nbtype, (types.Boolean, types.Integer, types.Float, types.Complex)):
        return str(nbtype)
    if isinstance(nbtype, types.BaseTuple):
        keys = tuple(type_key(t) for t in nbtype.types)
        return None if None in keys else ("tuple",) + keys
    if isinstance(nbtype, types.NoneType):
        return "none"
    return None


def used_signatures() -> list[tuple[str, str, object, tuple, object]]:
    """(module, qualname, dispatcher, argument types, return type) of every signature compiled so far by a
    serial Kinetre kernel defined at a module's top level."""
    from numba.core.registry import CPUDispatcher
    found, seen = [], set()
    for module_name, module in sorted(sys.modules.items(), key=lambda item: item[0]):
        if module is None or module_name.partition(".")[0] != "kinetre":
            continue
        for value in list(vars(module).values()):
            if not isinstance(value, CPUDispatcher) or id(value) in seen or value.py_func.__module__ != module_name:
                continue
            seen.add(id(value))
            if value.targetoptions.get("parallel"):
                continue
            for args in value.signatures:
                found.append((module_name, value.py_func.__qualname__, value, tuple(args),
                              value.overloads[args].signature.return_type))
    return found


def export_compiled(signatures=None, folder: Path | None = None) -> tuple[Path, int]:
    """Compile `signatures` (default: `used_signatures()`) into the extension module in `folder` (default:
    `jit.compiled_dir()`), replacing any other compiled kernels beside it. Returns the folder and the count."""
    numba = load_numba()
    from numba.pycc import CC
    from numba.pycc import compiler as pycc_compiler

    signatures = used_signatures() if signatures is None else signatures
    folder = compiled_dir() if folder is None else Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    build = Path(tempfile.mkdtemp(prefix=".building-", dir=folder.parent))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numba.pycc's pending-deprecation notice
            cc = CC(COMPILED_MODULE)
        cc.output_dir, cc.target_cpu, cc.verbose = str(build), "host", False
        listing = []
        for module_name, qualname, dispatcher, args, returns in signatures:
            keys = tuple(type_key(t) for t in args)
            if None in keys:
                continue
            symbol = f"k{len(listing)}"
            cc.export(symbol, returns(*args))(_entry(dispatcher, len(args)))
            listing.append([module_name, qualname, keys, symbol])
        original = pycc_compiler.compile_extra
        pycc_compiler.compile_extra = _releasing_gil(original)
        try:
            cc.compile()
        finally:
            pycc_compiler.compile_extra = original
        (build / COMPILED_TABLE).write_text(json.dumps({"file": cc.output_file, "numba": numba.__version__,
                                                        "kernels": listing}))
        if folder.exists():
            shutil.rmtree(folder)
        os.replace(build, folder)
    finally:
        shutil.rmtree(build, ignore_errors=True)
    for other in folder.parent.iterdir():  # compiled for sources or versions no longer installed
        if other != folder and other.is_dir() and not other.name.startswith(".building-"):
            shutil.rmtree(other, ignore_errors=True)
    return folder, len(listing)


def _entry(dispatcher, arity: int):
    """A function of `arity` arguments calling `dispatcher`: what the AOT compiler exports."""
    names = ", ".join(f"a{i}" for i in range(arity))
    space = {"kernel": dispatcher}
    exec(f"def entry({names}):\n    return kernel({names})\n", space)
    entry = space["entry"]
    entry.release_gil = bool(dispatcher.targetoptions.get("nogil"))
    return entry


def _releasing_gil(compile_extra):
    """numba.pycc compiles every export with the same flags: an entry of a nogil kernel releases the GIL."""
    def compile_entry(typingctx, targetctx, func, args, return_type, flags, locals, **kwargs):
        if getattr(func, "release_gil", False):
            flags = flags.copy()
            flags.release_gil = True
        return compile_extra(typingctx, targetctx, func, args, return_type, flags, locals, **kwargs)
    return compile_entry
