"""A take as a video: the deformed mesh, shaded, on a ground plane with its shadow, optionally with the
driving skeleton drawn over it, encoded by ffmpeg (H.264 MP4 or VP9 WebM).

Frames are rendered offscreen on the CPU (see `kinetre.export.render` for why moderngl + EGL/llvmpipe)
and piped as raw RGB into the `ffmpeg` command line tool (Debian `ffmpeg`), which owns the encoding.
"""
from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from ..deform.pose import GraphPose
from ..deform.skinning import SkinTable
from ..errors import ExportError
from ..graph.graph import DeformationGraph
from ..mesh.mesh import Mesh
from ..skeleton.models import Skeleton
from .render import Camera, MeshRenderer, cluster_lod

_CODECS = {
    # yuv420p + faststart: plays in browsers and QuickTime; CRF 20 is visually clean for flat-shaded scenes
    ".mp4": ["-c:v", "libx264", "-preset", "veryfast", "-crf", "20", "-pix_fmt", "yuv420p",
             "-movflags", "+faststart"],
    ".webm": ["-c:v", "libvpx-vp9", "-crf", "32", "-b:v", "0", "-deadline", "realtime", "-cpu-used", "8",
              "-pix_fmt", "yuv420p"],
}
BONE_RGB, JOINT_RGB = (30, 110, 235), (255, 140, 0)


def write_video(path, mesh: Mesh, graph: DeformationGraph, poses: list[GraphPose], fps: float,
                skeletons: list[list[Skeleton]] | None = None, size=(640, 480), *,
                on_frame: Callable[[int], None] | None = None, max_faces: int = 60_000) -> None:
    """Render the take to an .mp4 (H.264) or .webm (VP9) file, one video frame per pose.

    Parameters
    ----------
    path : str or Path
        Output file; the extension picks the codec.
    mesh, graph : Mesh, DeformationGraph
        The mesh and the graph that skins it.
    poses : list of GraphPose
        One pose per frame.
    fps : float
        Frame rate of the take, and of the video.
    skeletons : list (one per frame) of lists of Skeleton, optional
        Skeletons to draw over the mesh (bones between tracked joints), in the mesh's coordinates.
    size : (width, height) ints
        Even numbers (the 4:2:0 chroma subsampling needs them).
    on_frame : callable, optional
        Called with the frame index after each frame is encoded (for progress bars).
    max_faces : int
        Larger meshes are drawn through a vertex-clustered level of detail of this many triangles
        (`render.cluster_lod`): at 640x480 the difference is sub-pixel and the frame rate stays usable.

    Raises
    ------
    ExportError
        Unknown extension, odd size, no frames, skeleton list of the wrong length, ffmpeg or OpenGL
        missing, or ffmpeg failing (its last message is quoted).
    """
    path = Path(path)
    width, height = check_video_target(path, size, fps, len(poses))
    if skeletons is not None and len(skeletons) != len(poses):
        raise ExportError(f"{path}: {len(skeletons)} skeleton frames for {len(poses)} poses")

    try:
        lo, hi = take_bounds(mesh, graph, poses, skeletons)
    except ExportError as err:
        raise ExportError(f"{path}: {err}") from None
    camera = Camera(lo, hi, (width, height))
    colors = mesh.colors
    texture = material_image(mesh.material) if mesh.uvs is not None else None
    if texture is not None:
        colors = np.full((len(mesh.vertices), 4), 255, np.uint8)   # the texture alone gives the colour
    keep, faces = cluster_lod(mesh.vertices, mesh.faces, max_faces)
    uvs = None if mesh.uvs is None else mesh.uvs[keep]
    colors = None if colors is None else colors[keep]
    joints, weights = graph.vertex_nodes[keep], graph.vertex_weights[keep]
    # float32 skinning into two reused buffers: what the renderer uploads
    points = SkinTable.prepare(mesh.vertices[keep], joints, weights, graph.node_count)
    directions = SkinTable.prepare(mesh.normals[keep], joints, weights, graph.node_count, directions=True)
    positions, normals = np.empty((len(keep), 3), np.float32), np.empty((len(keep), 3), np.float32)
    renderer = MeshRenderer(len(keep), faces, camera, (width, height), uvs=uvs, colors=colors, texture=texture)

    def frames():
        try:
            for k, pose in enumerate(poses):
                m = pose.node_matrices(graph.nodes)
                points.skin(m, positions)
                m[:, :3, 3] = 0.0               # normals follow the blended linear part only
                frame = renderer.render(positions, directions.skin(m, normals))
                if skeletons is not None and skeletons[k]:
                    frame = draw_skeletons(frame, skeletons[k], camera)
                yield frame
                if on_frame is not None:
                    on_frame(k)
        finally:
            renderer.release()

    encode_video(path, frames(), fps, (width, height))


def check_video_target(path: Path, size, fps: float, count: int) -> tuple[int, int]:
    """Check the extension, an even frame size, fps and a frame count > 0; return (width, height)."""
    if path.suffix.lower() not in _CODECS:
        raise ExportError(f"{path}: a video must end in .mp4 or .webm, got {path.suffix.lower() or 'no extension'!r}")
    width, height = (int(s) for s in size)
    if width <= 0 or height <= 0 or width % 2 or height % 2:
        raise ExportError(f"{path}: video size must be two positive even numbers, got {tuple(size)}")
    if not count:
        raise ExportError(f"{path}: the take has no frames to render")
    if not np.isfinite(fps) or fps <= 0:
        raise ExportError(f"{path}: fps must be a positive number, got {fps}")
    if shutil.which("ffmpeg") is None:
        raise ExportError(f"{path}: video export needs the ffmpeg command (Debian package ffmpeg)")
    return width, height


def encode_video(path, frames, fps: float, size: tuple[int, int]) -> None:
    """Pipe (H, W, 3) uint8 RGB frames into ffmpeg, which encodes them by the extension (.mp4 H.264,
    .webm VP9). `frames` is any iterable (a generator renders while ffmpeg encodes)."""
    path = Path(path)
    width, height = size
    rate = Fraction(fps).limit_denominator(1001)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ExportError(f"{path}: cannot create the folder for the video ({err.strerror or err})") from None
    cmd = [shutil.which("ffmpeg"), "-y", "-hide_banner", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt",
           "rgb24", "-s", f"{width}x{height}", "-framerate", f"{rate.numerator}/{rate.denominator}", "-i", "-",
           *_CODECS[path.suffix.lower()], "-r", f"{rate.numerator}/{rate.denominator}", str(path)]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        for frame in frames:
            proc.stdin.write(np.ascontiguousarray(frame).tobytes())
        proc.stdin.close()
    except BrokenPipeError:
        pass                                  # ffmpeg died: its message is reported below
    finally:
        close = getattr(frames, "close", None)
        if close is not None:
            close()                           # a generator's cleanup (the renderer) runs now
        if proc.stdin and not proc.stdin.closed:
            try:
                proc.stdin.close()
            except BrokenPipeError:
                pass
        err = proc.stderr.read().decode(errors="replace").strip()
        code = proc.wait()
    if code != 0:
        last = err.splitlines()[-1] if err else f"exit status {code}"
        raise ExportError(f"{path}: ffmpeg could not encode the video: {last}")


def take_bounds(mesh, graph, poses, skeletons=None, sample: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """(3,) min and max corners over all frames of the deformed mesh (a vertex sample, Eq. 2) and of the
    tracked skeleton joints: what the camera frames and where the ground goes."""
    rng = np.random.default_rng(0)
    v = len(mesh.vertices)
    pick = np.arange(v) if v <= sample else np.union1d(rng.choice(v, sample, replace=False),
                                                        np.argmin(mesh.vertices, axis=0))
    idx, w = graph.vertex_nodes[pick], graph.vertex_weights[pick].astype(np.float64)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for pose in poses:
        m = pose.node_matrices(graph.nodes)[idx]                        # (S, 4, 4, 4)
        p = np.einsum("sk,skij,sj->si", w, m[..., :3, :3], mesh.vertices[pick]) + \
            np.einsum("sk,ski->si", w, m[..., :3, 3])
        lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
    for frame in skeletons or []:
        for s in frame:
            if s.tracked.any():
                lo = np.minimum(lo, s.positions[s.tracked].min(axis=0))
                hi = np.maximum(hi, s.positions[s.tracked].max(axis=0))
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        raise ExportError("the take's poses move the mesh to non-finite positions")
    return lo, hi


def material_image(material):
    """The base-colour image (PIL) of a trimesh material, or None."""
    if material is None:
        return None
    image = getattr(material, "baseColorTexture", None)
    if image is None:
        image = getattr(material, "image", None)
    return image if isinstance(image, Image.Image) else None


def draw_skeletons(frame: np.ndarray, skeletons: list[Skeleton], camera: Camera) -> np.ndarray:
    """(H, W, 3) uint8 frame with each skeleton's tracked bones and joints drawn on top."""
    h, w = frame.shape[:2]
    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    radius = max(2, round(h / 120))
    for s in skeletons:
        px = camera.project(s.positions, (w, h))
        for p, c in s.model.bones:
            if s.tracked[p] and s.tracked[c]:
                draw.line([tuple(px[p]), tuple(px[c])], fill=BONE_RGB, width=max(2, round(h / 160)))
        for j in np.flatnonzero(s.tracked):
            x, y = px[j]
            draw.ellipse([x - radius, y - radius, x + radius, y + radius], fill=JOINT_RGB)
    return np.asarray(image)
