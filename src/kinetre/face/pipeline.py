"""`kinetre face`: an image or a video → landmarks per frame → Algorithm 2 → frames ready to export.

A tracked face also gives FaceLandmarker's 52 blendshapes per frame; the take keeps them beside the frames
(the expression the puppet's shape came from), for the export to carry along.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BadFaceError
from ..skeleton.mediapipe import BLENDSHAPES
from .landmarks import FaceTracker, read_landmarks
from .reconstruct import FaceFrame, reconstruct
from .template import load_template

IMAGE_EXTS = (".jpg", ".jpeg", ".png", ".bmp", ".webp", ".tif", ".tiff")


@dataclass(frozen=True)
class FaceTake:
    """Reconstructed frames, the first frame's encoded image (the texture), its MIME type, the frame rate
    and how many frames had a face of their own (the others hold the last good one); blendshapes
    (len(frames), 52) the tracker's weights of the face each frame was rebuilt from (names
    `blendshape_names`), None when the landmarks did not come from the tracker."""

    frames: list[FaceFrame]
    image: bytes
    mime: str
    fps: float
    tracked: int
    blendshapes: np.ndarray | None = None

    @property
    def blendshape_names(self) -> tuple[str, ...]:
        return BLENDSHAPES if self.blendshapes is not None else ()


def _encode(bgr: np.ndarray, path: Path) -> tuple[bytes, str]:
    import cv2
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 92])
    if not ok:
        raise BadFaceError(f"{path}: cannot encode the frame as a texture")
    return buf.tobytes(), "image/jpeg"


def face_from_image(path, landmark_file=None, *, turn: bool = False) -> FaceTake:
    """One photo: MediaPipe's landmarks, or those of `landmark_file` (for faces the tracker misses)."""
    import cv2
    path = Path(path)
    if not path.is_file():
        raise BadFaceError(f"{path}: no such image")
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise BadFaceError(f"{path}: not a readable image")
    h, w = bgr.shape[:2]
    blendshapes = None
    if landmark_file is not None:
        landmarks, lw, lh = read_landmarks(landmark_file)
        if (lw, lh) != (w, h):
            raise BadFaceError(f"{landmark_file}: made for a {lw}x{lh} image, but {path} is {w}x{h}")
    else:
        with FaceTracker(static_image=True) as tracker:
            found = tracker.face(bgr)
        if found is None:
            raise BadFaceError(f"{path}: no face found; annotate it on the studio's /annotate page and pass "
                               f"--landmarks FILE")
        landmarks, blendshapes = found.landmarks, found.blendshapes[None]
    try:
        frame = reconstruct(landmarks, w, h, turn=turn)
    except BadFaceError as e:
        raise BadFaceError(f"{path}: {e}") from None
    return FaceTake([frame], *_encode(bgr, path), fps=1.0, tracked=1, blendshapes=blendshapes)


def face_from_video(path, *, max_frames: int | None = None, turn: bool = False) -> FaceTake:
    """Every frame of a video; frames without a face (or too turned) keep the last good landmarks."""
    import cv2
    path = Path(path)
    if not path.is_file():
        raise BadFaceError(f"{path}: no such video")
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise BadFaceError(f"{path}: not a readable video")
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    frames, shapes, first, last, last_shapes, tracked, read = [], [], None, None, None, 0, 0
    try:
        with FaceTracker(static_image=False) as tracker:
            while max_frames is None or read < max_frames:
                ok, bgr = cap.read()
                if not ok:
                    break
                found = tracker.face(bgr, read / fps)
                read += 1
                if found is not None:
                    try:
                        last = reconstruct(found.landmarks, bgr.shape[1], bgr.shape[0], turn=turn)
                        last_shapes = found.blendshapes
                        tracked += 1
                        first = bgr if first is None else first
                    except BadFaceError:
                        pass              # tracking loss keeps the last good face
                if last is not None:
                    frames.append(last)
                    shapes.append(last_shapes)
    finally:
        cap.release()
    if not read:
        raise BadFaceError(f"{path}: no frames could be read")
    if first is None:
        raise BadFaceError(f"{path}: no face found in any of its {read} frames")
    # the texture is the first frame with a face: the exported mesh starts there
    return FaceTake(frames, *_encode(first, path), fps=float(fps), tracked=tracked, blendshapes=np.array(shapes))


def face_take(path, landmark_file=None, *, max_frames: int | None = None, turn: bool = False) -> FaceTake:
    """Image or video by extension (frames without caricature: the export carries those as morphs)."""
    if str(path).lower().endswith(IMAGE_EXTS):
        return face_from_image(path, landmark_file, turn=turn)
    if landmark_file is not None:
        raise BadFaceError(f"{landmark_file}: a landmark file goes with a still image, not a video")
    return face_from_video(path, max_frames=max_frames, turn=turn)


def face_from_landmarks(frames, width: int, height: int, image: bytes, mime: str, fps: float,
                        *, turn: bool = False) -> FaceTake:
    """A take recorded elsewhere (the studio page): per-frame landmarks (468, 2|3) pixels, None when lost."""
    out, last = [], None
    n = load_template().size
    for k, landmarks in enumerate(frames):
        if landmarks is not None:
            landmarks = np.asarray(landmarks, dtype=float)
            if landmarks.shape not in ((n, 2), (n, 3)) or not np.isfinite(landmarks).all():
                raise BadFaceError(f"face take: frame {k} must hold {n} finite landmarks, got shape {landmarks.shape}")
            try:
                last = reconstruct(landmarks, width, height, turn=turn)
            except BadFaceError:
                pass                      # a head turned too far: keep the last good face
        if last is not None:
            out.append(last)
    if not out:
        raise BadFaceError("face take: no frame holds a face")
    return FaceTake(out, image, mime, fps=fps, tracked=sum(f is not None for f in frames))
