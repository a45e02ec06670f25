"""RGB-D sequences on disk: TUM (rgb.txt/depth.txt) and Redwood (color/ + depth/) layouts, and intrinsics.

A sequence is read lazily: `open_sequence` checks the folder, pairs colour with depth and settles the camera;
`read_frame` loads one pair as arrays (colour (H, W, 3) uint8, depth (H, W) float32 metres, 0 = no data).

Intrinsics come, in this order, from `--intrinsics FILE`, `intrinsics.json` in the folder, the single
PinholeCameraIntrinsic `*.json` in the folder, or a named camera (`CAMERAS`). The JSON is Open3D's
PinholeCameraIntrinsic (`width`, `height`, column-major `intrinsic_matrix`); a TXT file holds the 3x3 matrix
row by row (TUM/Redwood style), its size taken from the depth images.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from ..errors import BadScanError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
# no depth camera makes bigger frames; a larger declared size is a broken or hostile file
MAX_SIDE = 16384
# what PIL raises for a file it cannot decode, a truncated one, or one declaring billions of pixels
IMAGE_ERRORS = (OSError, ValueError, SyntaxError, Image.DecompressionBombError)
# TUM's associate.py pairs rgb/depth stamps closer than 20 ms.
TUM_MAX_DIFFERENCE = 0.02


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole camera: image size in pixels, focal lengths and principal point in pixels."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def matrix(self) -> np.ndarray:
        """(3, 3) float64 camera matrix K."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def scaled(self, width: int, height: int) -> "Intrinsics":
        """The same camera at another resolution (focal lengths and centre scale with the image)."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(width, height, self.fx * sx, self.fy * sy,
                          (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5)


# Named camera defaults (640x480 depth). PrimeSense/Kinect v1 is Open3D's default; TUM freiburg1/2/3 are the
# calibrations published with the TUM RGB-D benchmark.
CAMERAS: dict[str, Intrinsics] = {
    "primesense": Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "kinect": Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "kinect-v1": Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "tum-fr1": Intrinsics(640, 480, 517.3, 516.5, 318.6, 255.3),
    "tum-fr2": Intrinsics(640, 480, 520.9, 521.0, 325.1, 249.7),
    "tum-fr3": Intrinsics(640, 480, 535.4, 539.2, 320.1, 247.6),
}


@dataclass(frozen=True)
class RGBDSequence:
    """A paired, ordered RGB-D sequence.

    Attributes
    ----------
    depth_paths : tuple of Path, one per frame (16-bit PNG)
    color_paths : tuple of Path or None (depth-only sequence)
    timestamps : (N,) float64 seconds (TUM) or frame indices (Redwood)
    intrinsics : Intrinsics of the depth camera (colour is registered to depth)
    depth_scale : raw depth value per metre (1000 = millimetres, TUM uses 5000)
    layout : "tum" or "redwood"
    scale_source : where depth_scale came from (given, or the layout's default)
    """

    root: Path
    depth_paths: tuple[Path, ...]
    color_paths: tuple[Path, ...] | None
    timestamps: np.ndarray
    intrinsics: Intrinsics
    depth_scale: float
    layout: str
    scale_source: str = "given"

    def __len__(self) -> int:
        return len(self.depth_paths)


def read_intrinsics(path: str | Path, size: tuple[int, int] | None = None) -> Intrinsics:
    """Read an Open3D PinholeCameraIntrinsic JSON, or a TXT 3x3 matrix (needs `size` = (width, height))."""
    path = Path(path)
    if not path.is_file():
        raise BadScanError(f"{path}: intrinsics file not found")
    text = path.read_text(errors="replace")
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(text)
            k = np.asarray(data["intrinsic_matrix"], dtype=float).reshape(3, 3).T  # stored column-major
            width, height = int(data["width"]), int(data["height"])
        except (ValueError, KeyError, TypeError, OverflowError) as exc:
            raise BadScanError(f"{path}: not an Open3D PinholeCameraIntrinsic JSON "
                               f"(needs width, height, 9-value intrinsic_matrix): {exc}") from None
    else:
        try:
            values = np.array(text.split(), dtype=float)
        except ValueError:
            raise BadScanError(f"{path}: intrinsics TXT must hold 9 numbers (3x3 matrix)") from None
        if values.size != 9:
            raise BadScanError(f"{path}: intrinsics TXT must hold 9 numbers (3x3 matrix), got {values.size}")
        if size is None:
            raise BadScanError(f"{path}: a TXT intrinsics matrix needs the image size")
        k = values.reshape(3, 3)
        width, height = size
    if not (np.all(np.isfinite(k)) and k[0, 0] > 0 and k[1, 1] > 0 and 0 < width <= MAX_SIDE
            and 0 < height <= MAX_SIDE):
        raise BadScanError(f"{path}: intrinsics must have positive focal lengths and a size of 1..{MAX_SIDE} "
                           f"pixels, got fx={k[0, 0]} fy={k[1, 1]} size={width}x{height}")
    return Intrinsics(width, height, float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]))


def find_intrinsics(root: Path) -> Path | None:
    """`intrinsics.json` in `root`, else its only JSON file that is a PinholeCameraIntrinsic, else None."""
    named = root / "intrinsics.json"
    if named.is_file():
        return named
    found = []
    for path in sorted(root.glob("*.json")):
        try:
            data = json.loads(path.read_text(errors="replace"))
        except ValueError:
            continue
        if isinstance(data, dict) and {"width", "height", "intrinsic_matrix"} <= data.keys():
            found.append(path)
    if len(found) > 1:
        raise BadScanError(f"{root}: several camera intrinsics files ({', '.join(p.name for p in found)}); "
                           "name one intrinsics.json or pass --intrinsics")
    return found[0] if found else None


def _read_tum_list(path: Path) -> tuple[np.ndarray, list[Path]]:
    stamps, files = [], []
    for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        try:
            stamps.append(float(parts[0]))
            files.append(path.parent / parts[1])
        except (ValueError, IndexError):
            raise BadScanError(f"{path}:{number}: expected 'timestamp filename', got {line!r}") from None
        # an upload must not name other files; the name is judged as written, so a folder the user linked in stays readable
        named = os.path.normpath(parts[1])
        if os.path.isabs(named) or named == ".." or named.startswith(".." + os.sep):
            raise BadScanError(f"{path}:{number}: {parts[1]!r} lies outside the frames folder")
    return np.asarray(stamps, dtype=float), files


def associate(depth_stamps: np.ndarray, color_stamps: np.ndarray,
              max_difference: float = TUM_MAX_DIFFERENCE) -> np.ndarray:
    """For each depth stamp, the index of the nearest colour stamp, or -1 when none is within max_difference.

    Greedy one-to-one by increasing time difference, as TUM's associate.py does. Stamps are (N,) float64 seconds.
    """
    pairs = []
    for i, t in enumerate(depth_stamps):
        diff = np.abs(color_stamps - t)
        for j in np.flatnonzero(diff < max_difference):
            pairs.append((diff[j], i, j))
    pairs.sort()
    match = np.full(len(depth_stamps), -1, dtype=np.int64)
    used = set()
    for _, i, j in pairs:
        if match[i] < 0 and j not in used:
            match[i] = j
            used.add(j)
    return match


def _images_in(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())


def _layout(root: Path) -> tuple[str, list[Path], list[Path] | None, np.ndarray]:
    if (root / "rgb.txt").is_file() or (root / "depth.txt").is_file():
        if not (root / "depth.txt").is_file():
            raise BadScanError(f"{root}: TUM layout has rgb.txt but no depth.txt")
        d_stamps, d_files = _read_tum_list(root / "depth.txt")
        if not (root / "rgb.txt").is_file():
            return "tum", d_files, None, d_stamps
        c_stamps, c_files = _read_tum_list(root / "rgb.txt")
        match = associate(d_stamps, c_stamps)
        if not d_files or not c_files:
            return "tum", d_files, c_files or None, d_stamps
        if np.count_nonzero(match >= 0) < len(d_files):
            unmatched = len(d_files) - int(np.count_nonzero(match >= 0))
            raise BadScanError(f"{root}: {unmatched} of {len(d_files)} depth frames in depth.txt have no colour "
                               f"frame in rgb.txt within {TUM_MAX_DIFFERENCE * 1000:.0f} ms "
                               f"({len(c_files)} colour frames listed)")
        return "tum", d_files, [c_files[j] for j in match], d_stamps
    depth_dir = root / "depth"
    if depth_dir.is_dir():
        depth = _images_in(depth_dir)
        color_dir = next((root / n for n in ("color", "rgb", "image") if (root / n).is_dir()), None)
        color = _images_in(color_dir) if color_dir is not None else None
        if color is not None and len(color) != len(depth):
            raise BadScanError(f"{root}: {len(depth)} depth images in depth/ but {len(color)} colour images in "
                               f"{color_dir.name}/; the counts must match")
        return "redwood", depth, color, np.arange(len(depth), dtype=float)
    raise BadScanError(f"{root}: no RGB-D frames (expected TUM rgb.txt + depth.txt, or color/ and depth/ folders)")


def _image_size(path: Path) -> tuple[int, int]:
    try:
        with Image.open(path) as image:
            size = image.size
    except IMAGE_ERRORS as exc:
        raise BadScanError(f"{path}: unreadable image ({exc})") from None
    if not (0 < size[0] <= MAX_SIDE and 0 < size[1] <= MAX_SIDE):
        raise BadScanError(f"{path}: an image of {size[0]}x{size[1]} pixels is not a depth camera's frame")
    return size


def open_sequence(root: str | Path, intrinsics: str | Path | Intrinsics | None = None,
                  depth_scale: float | None = None, camera: str | None = None) -> RGBDSequence:
    """Find, pair and check the frames in `root`; settle intrinsics and depth scale.

    depth_scale defaults to 5000 for TUM and 1000 otherwise. `camera` names an entry of CAMERAS used when no
    intrinsics file is given or found. Raises BadScanError for a missing folder, no frames, mismatched counts or
    missing intrinsics.
    """
    root = Path(root)
    if not root.is_dir():
        raise BadScanError(f"{root}: frames folder not found")
    layout, depth, color, stamps = _layout(root)
    if not depth:
        raise BadScanError(f"{root}: no depth frames found ({layout} layout)")
    width, height = _image_size(depth[0])
    if isinstance(intrinsics, Intrinsics):
        cam = intrinsics
    elif intrinsics is not None:
        cam = read_intrinsics(intrinsics, (width, height))
    elif (found := find_intrinsics(root)) is not None:
        cam = read_intrinsics(found, (width, height))
    elif camera is not None:
        if camera.lower() not in CAMERAS:
            raise BadScanError(f"unknown camera {camera!r}; known: {', '.join(CAMERAS)}")
        cam = CAMERAS[camera.lower()]
    else:
        raise BadScanError(f"{root}: no camera intrinsics (no intrinsics.json in the folder); pass --intrinsics "
                           f"FILE or --camera NAME ({', '.join(CAMERAS)})")
    if (cam.width, cam.height) != (width, height):
        # A named camera or file made for another resolution of the same sensor: scale it.
        cam = cam.scaled(width, height)
    scale = float(depth_scale) if depth_scale is not None else (5000.0 if layout == "tum" else 1000.0)
    if not np.isfinite(scale) or scale <= 0:
        raise BadScanError(f"depth scale must be a positive number, got {depth_scale}")
    source = ("given" if depth_scale is not None else
              "the TUM layout's default" if layout == "tum" else "the default for millimetre depth")
    return RGBDSequence(root, tuple(depth), tuple(color) if color else None, stamps, cam, scale, layout, source)


def read_frame(sequence: RGBDSequence, index: int) -> tuple[np.ndarray, np.ndarray]:
    """Frame `index` as (colour (H, W, 3) uint8, depth (H, W) float32 metres; 0 where the sensor saw nothing).

    Raises BadScanError for an unreadable file, 8-bit depth, a size that differs from the intrinsics, or a depth
    image with no valid pixel.
    """
    path = sequence.depth_paths[index]
    try:
        with Image.open(path) as image:
            mode = image.mode
            raw = np.asarray(image)
    except IMAGE_ERRORS as exc:
        raise BadScanError(f"{path}: unreadable depth image ({exc})") from None
    if raw.dtype == np.uint8 or mode in ("L", "P", "RGB", "RGBA", "LA"):
        raise BadScanError(f"{path}: depth must be a 16-bit single-channel image, got 8-bit mode {mode!r} "
                           "(depth saved as 8 bits loses the distance)")
    if raw.ndim != 2:
        raise BadScanError(f"{path}: depth must be single-channel, got shape {raw.shape}")
    cam = sequence.intrinsics
    if raw.shape != (cam.height, cam.width):
        raise BadScanError(f"{path}: depth is {raw.shape[1]}x{raw.shape[0]} but the camera is "
                           f"{cam.width}x{cam.height}")
    depth = raw.astype(np.float32) / np.float32(sequence.depth_scale)
    depth[~np.isfinite(depth)] = 0.0
    if not np.any(depth > 0):
        raise BadScanError(f"{path}: empty depth frame (no pixel has a depth)")
    if sequence.color_paths is None:
        color = np.full((cam.height, cam.width, 3), 128, dtype=np.uint8)
    else:
        cpath = sequence.color_paths[index]
        try:
            with Image.open(cpath) as image:
                color = np.asarray(image.convert("RGB"))
        except IMAGE_ERRORS as exc:
            raise BadScanError(f"{cpath}: unreadable colour image ({exc})") from None
        if color.shape[:2] != depth.shape:
            with Image.fromarray(color) as image:  # colour registered to depth at another resolution
                color = np.asarray(image.resize((cam.width, cam.height), Image.BILINEAR))
    return np.ascontiguousarray(color), depth

