"""What a scan read from its depth images, and whether the object it kept fits those depths.

Raw depth values become metres by one number, the depth scale (raw units per metre: 1000 for millimetres,
5000 in the TUM benchmark's files). A wrong one scales the whole scene: millimetre depth read at TUM's 5000
puts a room within half a metre of the camera and makes a lamp 11 cm tall. Every threshold of the pipeline
is metric (the voxel, the plane margin, what counts as a speck), so in such a shrunken scene thin parts fall
apart and what is kept is a fragment: a piece that spans a small part of the view at the depths read.

So the scan reports the depth range it read with the scale that gave it, and warns when the kept object's
widest extent is under `SMALL_IN_VIEW` of the view's width at the median depth read: it was looked at from
there, so it should fill more of the picture (an object scanned on purpose fills a third or more; the
fragment above fills a sixth).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SMALL_IN_VIEW = 0.25
STRIDE = 16        # pixels sampled per row and column of each frame for the range (percentiles need no more)
COMMON_SCALES = (1000.0, 5000.0)   # millimetres; the TUM benchmark's fifth-millimetres


@dataclass(frozen=True)
class DepthReading:
    """The depths read, in metres: 1st percentile, median and 99th percentile of every valid pixel sampled,
    the fraction beyond `depth_max` (ignored by fusion), and the depth scale with where it came from."""

    near: float
    median: float
    far: float
    beyond: float
    depth_max: float
    scale: float
    scale_source: str

    def line(self) -> str:
        """One report line."""
        text = (f"depth: read {self.near:.2f}-{self.far:.2f} m (median {self.median:.2f} m) at depth scale "
                f"{self.scale:g} raw units per metre ({self.scale_source})")
        if self.beyond > 0.005:
            text += f"; {100 * self.beyond:.0f} % of the pixels lie beyond {self.depth_max:g} m and are ignored"
        return text

    def alternatives(self) -> str:
        """The other common scales and the median depth each would give."""
        raw = self.median * self.scale
        return ", ".join(f"--depth-scale {s:g} reads the median at {raw / s:.2f} m" for s in COMMON_SCALES
                         if s != self.scale)


def sample_depths(depth: np.ndarray) -> np.ndarray:
    """The valid depths (> 0) of a grid of pixels of one frame, for `depth_reading`."""
    d = depth[::STRIDE, ::STRIDE]
    return d[d > 0].astype(np.float32)


def depth_reading(samples: list, scale: float, scale_source: str, depth_max: float) -> DepthReading:
    """Summarise the per-frame `sample_depths` of a sequence."""
    d = np.concatenate(samples) if samples else np.zeros(0, np.float32)
    if not d.size:
        return DepthReading(0.0, 0.0, 0.0, 0.0, depth_max, scale, scale_source)
    near, median, far = (float(v) for v in np.percentile(d, [1, 50, 99]))
    return DepthReading(near, median, far, float(np.mean(d > depth_max)), depth_max, scale, scale_source)


def size_warning(reading: DepthReading, extent: float, width: int, fx: float) -> str | None:
    """A warning when an object `extent` metres wide is implausibly small for the depths read (see above)."""
    if reading.median <= 0:
        return None
    view = reading.median * width / fx           # the view's width at the median depth
    if extent >= SMALL_IN_VIEW * view:
        return None
    return (f"the kept object is {100 * extent:.1f} cm across, {100 * extent / view:.0f} % of the view's "
            f"{100 * view:.0f} cm width at the median depth read ({reading.median:.2f} m): probably a fragment. "
            f"If the depth scale is wrong, the whole scene is scaled ({reading.alternatives()}); check the "
            f"depth images' unit")
