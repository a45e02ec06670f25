"""A motion source is an interface: every source (BVH, glTF animation, recorded take, video) yields a `Take`.

A take is a whole clip of skeleton frames in one canonical frame: metres, +Y up, with a tracked mask.
`load_take` picks the reader by file extension (a registry, as trimesh's loaders do).
"""
from __future__ import annotations

import math
import os
from dataclasses import replace

import numpy as np

from ..errors import BadMotionError
from .bvh import load_bvh
from .gltf import load_gltf, split_animation
from .stream import read_stream
from .take import Take

__all__ = ["Take", "READERS", "load_take", "resample"]


def capture_video(path: str | os.PathLike) -> Take:
    """`motion.capture.capture_video`: the tracker's modules are imported when a video is read, not with
    every motion file."""
    from .capture import capture_video as track
    return track(path)


# Extension -> reader(path, **options); compound extensions are matched first.
READERS = {".kinetre.jsonl": read_stream, ".jsonl": read_stream, ".bvh": load_bvh,
           ".mp4": capture_video, ".mov": capture_video, ".avi": capture_video, ".mkv": capture_video,
           ".webm": capture_video, ".glb": load_gltf, ".gltf": load_gltf, ".vrma": load_gltf}
_TAKES_OPTIONS = {load_bvh, load_gltf}  # readers that accept keyword options


def load_take(path: str | os.PathLike, **options) -> Take:
    """Read any motion file into a `Take`: BVH, a glTF animation, a recorded `.kinetre.jsonl` stream, or a video.

    A glTF path may end in `#NAME` or `#INDEX` to pick the animation. `options` go to the reader (BVH:
    `scale`, `as_kinect`; glTF: `animation`, `fps`, `as_kinect`).

    Examples
    --------
    >>> load_take("walk.fbx")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    kinetre.errors.BadMotionError: walk.fbx: unknown motion format (expected one of .kinetre.jsonl, ...)
    """
    name = split_animation(path)[0].lower()
    for ext, reader in sorted(READERS.items(), key=lambda kv: -len(kv[0])):
        if name.endswith(ext):
            return reader(path, **options) if reader in _TAKES_OPTIONS else reader(path)
    raise BadMotionError(f"{path}: unknown motion format (expected one of {', '.join(READERS)})")


def resample(take: Take, fps: float) -> Take:
    """The take at another frame rate, positions interpolated linearly in time.

    A joint is tracked in a new frame when it is tracked in both original frames around it; everyone's
    joints, hands and blendshapes are interpolated likewise (a hand or face seen in only one of the two
    frames is not seen). An integer ratio down (120 -> 30 fps) just keeps every n-th frame, so those frames
    stay bit-exact.
    """
    if not (math.isfinite(fps) and fps > 0):
        raise BadMotionError(f"{take.source or 'take'}: fps must be a positive number, got {fps!r}")
    ratio = take.fps / fps
    if round(ratio) >= 1 and abs(ratio - round(ratio)) < 1e-4 * ratio:
        kept = take.slice(0, None, int(round(ratio)))
        return replace(kept, fps=float(fps))
    n = int(math.floor(take.duration * fps + 1e-9)) + 1
    x = np.arange(n) * take.fps / fps  # position in original frames
    i0 = np.minimum(np.floor(x).astype(int), len(take) - 1)
    i1 = np.minimum(i0 + 1, len(take) - 1)
    a = x - i0
    exact = a < 1e-9  # on an original frame: its neighbour does not matter (nor its NaNs)

    def lerp(values):
        if values is None:
            return None
        shape = (n,) + (1,) * (values.ndim - 1)
        w, on = a.reshape(shape), exact.reshape(shape)
        return np.where(on, values[i0], (1 - w) * values[i0] + w * values[i1])

    def both(flags):
        return None if flags is None else flags[i0] & (flags[i1] | exact.reshape((n,) + (1,) * (flags.ndim - 1)))
    return Take(take.model, lerp(take.positions), both(take.tracked), fps, take.source, take.people,
                lerp(take.crowd_positions), both(take.crowd_tracked), lerp(take.hands), lerp(take.blendshapes),
                take.blendshape_names, applied=take.applied)
