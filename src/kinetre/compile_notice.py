"""The one line a command prints when it has to compile Kinetre's kernels (the first run after an install or an
upgrade that `make setup` did not warm): what the wait is for. numba-free, so the command line can ask for it
before it knows whether the command will load any kernel."""
from __future__ import annotations

from collections.abc import Callable

LINE = ("kinetre: compiling the numeric kernels on first use (once per version, up to a minute; "
        "`make setup` compiles them ahead)")

_say: list[Callable[[str], None]] = []


def announce_compiling(say: Callable[[str], None]) -> None:
    """Call `say(LINE)` once in this process, when the first kernel is found missing from the cache."""
    _say[:] = [say]


def compiling() -> None:
    """A kernel is about to be compiled (`kinetre.jit` calls this): say so the first time."""
    if _say:
        _say.pop()(LINE)
