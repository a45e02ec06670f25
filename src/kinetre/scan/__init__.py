"""Scanning (KinÊtre paper, "Acquisition, Segmentation and Meshing"): RGB-D frames → frame-to-model
tracking → TSDF fusion → segmentation → clean mesh.

Needs the `scan` extra (Open3D); importing this package does not, only running a scan does.

    >>> from kinetre.scan import scan                                    # doctest: +SKIP
    >>> print(scan("frames/", "chair.ply", segment="plane").summary())    # doctest: +SKIP
"""
from ..lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {"ScanResult": ".pipeline", "scan": ".pipeline",
                                               "scan_zip": ".pipeline"})

__all__ = ["ScanResult", "scan", "scan_zip"]
