"""Skeletons from video, a webcam or a photo with MediaPipe Pose (Python side of live capture).

Each image goes through `mp.solutions.pose.Pose(model_complexity=1)` (the model inside the mediapipe
0.10.14 wheel; complexities 0 and 2 would be downloaded), its 33 landmarks become Kinect-20
(`kinetre.skeleton.mediapipe`), the body is placed in camera space from the image landmarks (so jumps and
walking show), turned to +Y up facing +Z, and smoothed with a One-Euro filter. Positions are metres in
the camera's frame: the camera at the origin, the person in front of it at negative z.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import BadMotionError
from ..skeleton.mediapipe import FLIP, kinect_from_mediapipe, root_translation
from ..skeleton.models import KINECT20, Skeleton
from .filters import OneEuroFilter
from .take import Take


@dataclass(frozen=True)
class CaptureSettings:
    """How images become skeletons.

    fov_degrees : assumed horizontal field of view of the camera (a typical webcam: 60°)
    visibility : landmarks below this MediaPipe visibility are not tracked
    smooth : apply the One-Euro filter (min_cutoff Hz, beta Hz per m/s) to joint positions
    default_depth : metres in front of the camera, used until the body can be placed from the image
    """

    fov_degrees: float = 60.0
    visibility: float = 0.5
    smooth: bool = True
    min_cutoff: float = 1.0
    beta: float = 20.0
    default_depth: float = 3.0


def _mediapipe_pose():
    try:
        import mediapipe as mp
    except ImportError:
        raise BadMotionError("video capture needs MediaPipe: pip install 'kinetre[capture]' "
                             "(mediapipe==0.10.14)") from None
    return mp.solutions.pose


class PoseTracker:
    """MediaPipe Pose over a sequence of images (or single photos with `static_image=True`).

    >>> with PoseTracker() as tracker:                                   # doctest: +SKIP
    ...     skeleton = tracker.track(bgr_image, t=0.0)
    """

    def __init__(self, settings: CaptureSettings = CaptureSettings(), static_image: bool = False):
        self.settings = settings
        self._pose = _mediapipe_pose().Pose(static_image_mode=static_image, model_complexity=1,
                                            smooth_landmarks=True, enable_segmentation=False)
        self._filter = OneEuroFilter(settings.min_cutoff, settings.beta) if settings.smooth else None
        self._root = None  # last camera-space translation

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        self._pose.close()

    def landmarks(self, bgr: np.ndarray):
        """(world (33, 3), image (33, 2), visibility (33,)) for a BGR uint8 image, or None without a person."""
        import cv2
        result = self._pose.process(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        if result.pose_world_landmarks is None or result.pose_landmarks is None:
            return None
        world = np.array([[p.x, p.y, p.z] for p in result.pose_world_landmarks.landmark])
        image = np.array([[p.x, p.y] for p in result.pose_landmarks.landmark])
        visibility = np.array([p.visibility for p in result.pose_landmarks.landmark])
        return world, image, visibility

    def track(self, bgr: np.ndarray, t: float) -> Skeleton:
        """The Kinect-20 skeleton in a BGR image taken at time `t` seconds (all untracked without a person)."""
        marks = self.landmarks(bgr)
        if marks is None:
            positions = np.full((len(KINECT20.joints), 3), np.nan)
        else:
            world, image, visibility = marks
            h, w = bgr.shape[:2]
            positions, tracked = kinect_from_mediapipe(world, visibility, self.settings.visibility)
            root = root_translation(world, image, visibility >= self.settings.visibility, w, h,
                                    self.settings.fov_degrees)
            if root is not None:
                self._root = root
            elif self._root is None:
                root = np.array([0.0, 0.0, self.settings.default_depth])
            positions = (positions + (self._root if root is None else root)) @ FLIP.T
            positions[~tracked] = np.nan
        if self._filter is not None:
            positions = self._filter(positions, t)
        return Skeleton(KINECT20, positions, np.isfinite(positions).all(axis=1))


def capture_image(path: str | os.PathLike, settings: CaptureSettings = CaptureSettings()) -> Skeleton:
    """The skeleton of the person in a photo. Raises BadMotionError if unreadable or nobody is found."""
    import cv2
    bgr = cv2.imread(os.fspath(path))
    if bgr is None:
        raise BadMotionError(f"{path}: cannot read the image")
    with PoseTracker(settings, static_image=True) as tracker:
        skeleton = tracker.track(bgr, 0.0)
    if not skeleton.tracked.any():
        raise BadMotionError(f"{path}: no person found in the image")
    return skeleton


def _open(source, label: str):
    import cv2
    level = cv2.getLogLevel()
    cv2.setLogLevel(0)  # silent while opening: our one-line error replaces OpenCV's log lines
    try:
        cap = cv2.VideoCapture(source)
    finally:
        cv2.setLogLevel(level)
    if not cap.isOpened():
        cap.release()
        raise BadMotionError(f"{label}: cannot open (not a readable video, or no such camera)")
    return cap


def capture_video(path: str | os.PathLike, settings: CaptureSettings = CaptureSettings(),
                  max_frames: int | None = None, progress: bool = False) -> Take:
    """Track every frame of a video file into a `Take` at the video's frame rate.

    Frames without a person are kept (all joints untracked) so timing stays true.

    Raises
    ------
    BadMotionError
        The file is missing or not a video, has no frames, or shows no person in any frame.
    """
    import cv2
    path = os.fspath(path)
    if not os.path.exists(path):
        raise BadMotionError(f"{path}: no such file")
    cap = _open(path, path)
    fps = cap.get(cv2.CAP_PROP_FPS)
    fps = fps if np.isfinite(fps) and 1.0 <= fps <= 1000.0 else 30.0
    total = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) or None
    if max_frames is not None:
        total = min(total or max_frames, max_frames)
    frames: list[Skeleton] = []
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=total, unit="frame", desc="tracking", leave=False, disable=None)  # terminals only
    try:
        with PoseTracker(settings) as tracker:
            while max_frames is None or len(frames) < max_frames:
                ok, bgr = cap.read()
                if not ok:
                    break
                frames.append(tracker.track(bgr, len(frames) / fps))
                if bar is not None:
                    bar.update(1)
    finally:
        cap.release()
        if bar is not None:
            bar.close()
    if not frames:
        raise BadMotionError(f"{path}: the video has no readable frames")
    take = Take.from_frames(frames, fps, path)
    if not take.tracked.any():
        raise BadMotionError(f"{path}: no person found in any of the {len(frames)} frames")
    return take


def capture_camera(index: int | str, on_frame, settings: CaptureSettings = CaptureSettings(),
                   seconds: float | None = None, max_frames: int | None = None) -> int:
    """Track a webcam until Ctrl-C, `seconds` or `max_frames`, calling `on_frame(skeleton, t)` per frame
    with `t` the wall-clock seconds since the start.

    `index` is a camera number, or a string OpenCV opens as a live source (an RTSP URL, a device path).
    Returns the number of frames captured. Raises BadMotionError if the camera cannot be opened.
    """
    import time
    cap = _open(index if isinstance(index, str) else int(index), f"camera {index}")
    count, start = 0, time.monotonic()
    try:
        with PoseTracker(settings) as tracker:
            while max_frames is None or count < max_frames:
                ok, bgr = cap.read()
                t = time.monotonic() - start
                if not ok or (seconds is not None and t > seconds):
                    break
                on_frame(tracker.track(bgr, t), t)
                count += 1
    except KeyboardInterrupt:
        pass  # Ctrl-C ends a recording; what was captured so far is kept
    finally:
        cap.release()
    return count
