"""Where Kinetre keeps per-user files that outlive a run (the tracking models, compiled kernels).

The platforms' usual cache folders, overridable by their usual variables:
Linux and other Unixes `$XDG_CACHE_HOME/kinetre` (default `~/.cache/kinetre`), macOS
`~/Library/Caches/kinetre`, Windows `%LOCALAPPDATA%\\kinetre\\Cache`.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["user_cache_dir"]


def user_cache_dir() -> Path:
    """The per-user cache folder (not created here)."""
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "kinetre" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "kinetre"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "kinetre"
