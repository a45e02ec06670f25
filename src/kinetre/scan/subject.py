"""RGB-D frames (a folder or a zip) to the mesh `kinetre animate` drives, and whether it looks like an object.

Calls the scan pipeline's public entries (`pipeline.scan`, `pipeline.scan_zip`) into a temporary file and
loads the result as a `Mesh` (metres, +Y up). A plane segmentation of a cluttered room can keep a piece of
wall instead of the object on the floor; `shape_notes` tells such a flat sheet apart by its principal
extents (a sheet's thinnest spread is a few percent of its widest; a chair, a cow or a teapot are > 25 %).
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from ..errors import BadScanError
from ..mesh.load import load_mesh
from ..mesh.mesh import Mesh

FLAT = 0.1  # thinnest / widest principal spread below which the scanned piece is a sheet, not an object


def is_frames(path: str | os.PathLike) -> bool:
    """A folder of RGB-D frames or a zip of one (what `kinetre animate` scans before rigging)."""
    p = Path(path)
    return p.is_dir() or p.suffix.lower() == ".zip"


def principal_spread(vertices: np.ndarray) -> np.ndarray:
    """(3,) standard deviations of the vertices along their principal axes, widest first.

    >>> principal_spread(np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0], [2, 1, 0.0]]))
    array([1. , 0.5, 0. ])
    """
    c = vertices - vertices.mean(axis=0)
    return np.sqrt(np.maximum(np.linalg.eigvalsh(c.T @ c / len(c)), 0.0))[::-1]


def shape_notes(mesh: Mesh, where: str) -> tuple[str, ...]:
    """Words for a scan result that does not look like an object to animate (empty when it does)."""
    spread = principal_spread(mesh.vertices)
    if spread[0] > 0 and spread[2] / spread[0] < FLAT:
        size = " x ".join(f"{s:.2f}" for s in np.ptp(mesh.vertices, axis=0))
        return (f"{where}: the scan segmented to a flat sheet ({size} m, its thinnest spread "
                f"{100 * spread[2] / spread[0]:.0f} % of its widest): probably a wall or the floor, not an "
                f"object; it is animated as it is. Scan the object with the plane it stands on in view from the "
                f"first frame, or use --segment change with --before",)
    return ()


def scan_subject(frames: str | os.PathLike, segment: str | None = "plane", before=None,
                 progress: bool = True, **options) -> tuple[Mesh, object, tuple[str, ...]]:
    """Scan `frames` (folder or .zip) and return (mesh, the pipeline's ScanResult, `shape_notes`); the scan's
    own warnings are on the result. `options` go to the scan (`voxel`, `intrinsics`, `depth_scale`, ...).

    Raises
    ------
    BadScanError
        Unusable frames (from the pipeline), or open3d missing (`pip install 'kinetre[scan]'`).
    """
    try:
        from .pipeline import scan, scan_zip
    except ModuleNotFoundError as e:
        if e.name == "open3d":
            raise BadScanError(f"{frames}: scanning RGB-D frames needs open3d: pip install 'kinetre[scan]'") \
                from None
        raise
    frames = os.fspath(frames)
    with tempfile.TemporaryDirectory(prefix="kinetre-animate-") as tmp:
        out = Path(tmp) / "scan.ply"
        if frames.lower().endswith(".zip"):
            if not os.path.isfile(frames):
                raise BadScanError(f"{frames}: no such file")
            result = scan_zip(frames, out, segment=segment, before=before, progress=progress, **options)
        else:
            result = scan(frames, out, segment=segment, before=before, progress=progress, **options)
        mesh = load_mesh(out)
    return mesh, result, shape_notes(mesh, frames)
