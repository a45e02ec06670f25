"""Package attributes imported on first use (PEP 562), so `import kinetre` and the command line's parser
cost milliseconds, not the second that numba, scipy and trimesh take: each command imports what it runs."""
from __future__ import annotations

import importlib


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
