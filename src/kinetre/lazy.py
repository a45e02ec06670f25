"""Package attributes imported on first use (PEP 562), so `import kinetre` and the command line's parser
cost milliseconds, not the second that numba, scipy and trimesh take: each command imports what it runs.
Likewise trimesh is imported with the modules it pulls in for features kinetre never uses deferred."""
from __future__ import annotations

import contextlib
import importlib
import sys


def lazy_exports(package: str, exports: dict[str, str]):
    """`__getattr__` and `__dir__` for a package whose public names live in submodules.

    Parameters
    ----------
    package : str
        The package's `__name__`.
    exports : dict
        Public name -> the submodule that defines it under that name, relative (".mesh.load"). A name that is
        also a submodule's cannot be lazy: importing the submodule would set the package attribute first.
    """
    def __getattr__(name: str):
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(exports[name], package), name)
        vars(importlib.import_module(package))[name] = value  # later look-ups skip __getattr__
        return value

    def __dir__():
        return sorted(set(vars(importlib.import_module(package))) | set(exports))

    return __getattr__, __dir__


# Modules trimesh 4-5's `__init__` imports for features kinetre never calls: bounding spheres (`nsphere`,
# which imports scipy.optimize), 2D path polygons and simplification, voxel morphology (scipy.ndimage).
TRIMESH_UNUSED = ("scipy.optimize", "scipy.ndimage", "trimesh.nsphere", "trimesh.path.polygons",
                  "trimesh.path.simplify")


def import_trimesh():
    """The `trimesh` module, imported with `TRIMESH_UNUSED` deferred (0.13-0.15 s less per process).

    A deferred module is a `importlib.util.LazyLoader` module: it runs its code the first time one of its
    attributes is used, so any caller that does use it gets the real module. Already imported modules (and
    trimesh itself, if imported first elsewhere) are left as they are.
    """
    if "trimesh" not in sys.modules:
        with deferred_imports(TRIMESH_UNUSED):
            import trimesh  # noqa: F401
    return sys.modules["trimesh"]


@contextlib.contextmanager
def deferred_imports(names):
    """While active, importing one of `names` (full dotted names) creates a lazy module (see `import_trimesh`)."""
    finder = _Deferred(frozenset(names))
    sys.meta_path.insert(0, finder)
    try:
        yield
    finally:
        sys.meta_path.remove(finder)


class _Deferred:
    """A meta path finder: finds `names` with the other finders and wraps their loaders in
    `importlib.util.LazyLoader` (importlib.util and importlib.abc are imported only when used: 30 ms of
    `kinetre --help`)."""

    def __init__(self, names: frozenset[str]):
        self.names = names

    def find_spec(self, name, path, target=None):
        if name not in self.names:
            return None
        for finder in sys.meta_path:
            find = getattr(finder, "find_spec", None)
            if finder is self or find is None:
                continue
            spec = find(name, path, target)
            if spec is not None:
                if spec.loader is not None and hasattr(spec.loader, "exec_module"):
                    import importlib.util
                    spec.loader = importlib.util.LazyLoader(spec.loader)
                return spec
        return None
