"""What the command-line commands share: the usage error, output types, frame ranges, motion loading."""
from __future__ import annotations

import os

from .errors import KinetreError


class UsageError(KinetreError):
    """A command-line argument that does not make sense (reported like any bad input)."""


def output_ext(path: str, choices) -> str:
    """The output type of `path` among `choices` (longest match first: `.kinetre.jsonl` before `.jsonl`)."""
    low = path.lower()
    for ext in sorted(choices, key=len, reverse=True):
        if low.endswith(ext):
            return ext
    raise UsageError(f"{path}: unsupported output type (expected {', '.join(choices)})")


def frame_range(spec: str | None) -> slice:
    """`--frames START:END` (either end may be empty) as a slice; no spec is every frame."""
    if not spec:
        return slice(None)
    parts = spec.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        start, stop = (int(p) if p.strip() else None for p in parts)
    except ValueError:
        raise UsageError(f"--frames must be START:END (e.g. 0:60), got {spec!r}") from None
    return slice(start, stop)


def load_motion(path: str, scale: float | None, as_kinect: bool = True):
    """A motion file (BVH, glTF animation, recorded take) as a Take; `--scale` and `--own-skeleton`
    apply only where the file has a skeleton of its own."""
    from .motion.gltf import is_gltf
    from .motion.source import load_take
    if is_gltf(path):
        if scale is not None:
            raise UsageError("--scale applies to BVH files only")
        return load_take(path, as_kinect=as_kinect)
    if not path.lower().endswith(".bvh") and (scale is not None or not as_kinect):
        raise UsageError("--scale and --own-skeleton apply to BVH and glTF files only")
    if path.lower().endswith(".bvh"):
        return load_take(path, scale=scale, as_kinect=as_kinect)
    return load_take(path)


def quiet_mediapipe() -> None:
    """Keep a command's stderr for its errors: MediaPipe's C++ side logs through glog/absl there."""
    os.environ.setdefault("GLOG_minloglevel", "2")
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
