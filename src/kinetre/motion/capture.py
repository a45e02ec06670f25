"""Skeletons from video, a webcam or a photo with MediaPipe's Tasks landmarkers (the Python side of capture).

Each image goes through the studio page's models (`kinetre.motion.landmarkers`: up to four bodies, their
hands and faces, over the image and its square tiles). Every body gets a stable id (`kinetre.motion.people`),
its 33 landmarks become Kinect-20 (`kinetre.skeleton.mediapipe`), the body is placed in camera space from
the image landmarks (so jumps and walking show), turned to +Y up facing +Z, and smoothed with a One-Euro
filter of its own. Hands go to the person whose wrist they start at, faces to the person whose nose they
have. Positions are metres in the camera's frame: the camera at the origin, the people at negative z.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import BadMotionError, BadSettingsError
from ..skeleton.mediapipe import BLENDSHAPES, FLIP, kinect_from_mediapipe, root_translation
from ..skeleton.models import KINECT20, Skeleton
from .filters import OneEuroFilter
from .landmarkers import Body, Face, Hand, Landmarkers
from .people import Tracks, assign_ids, main_person
from .take import PersonFrame, Take, crowd_take

_WRISTS = (15, 16)      # MediaPipe's left and right wrist: where a hand's landmark 0 should be
_TORSO = (11, 12, 23, 24)


@dataclass(frozen=True)
class CaptureSettings:
    """How images become skeletons.

    fov_degrees : assumed horizontal field of view of the camera (a typical webcam: 60°)
    visibility : landmarks below this MediaPipe visibility are not tracked
    smooth : apply the One-Euro filter (min_cutoff Hz, beta Hz per m/s) to joint positions
    default_depth : metres in front of the camera, used until a body can be placed from the image
    people : most people tracked at once (1 to 4)
    hands, face : also track hands (21 landmarks each) and faces (52 blendshapes)
    tiles : also search overlapping square crops of a wide image, where people are small
    memory : seconds someone may be out of view and keep their id
    """

    fov_degrees: float = 60.0
    visibility: float = 0.5
    smooth: bool = True
    min_cutoff: float = 1.0
    beta: float = 20.0
    default_depth: float = 3.0
    people: int = 4
    hands: bool = True
    face: bool = True
    tiles: bool = True
    memory: float = 3.0

    def __post_init__(self):
        if not (isinstance(self.people, int) and 1 <= self.people <= 4):
            raise BadSettingsError(f"people must be 1 to 4, got {self.people!r}")
        if not (0 < self.fov_degrees < 180):
            raise BadSettingsError(f"fov_degrees must be between 0 and 180, got {self.fov_degrees!r}")

    @property
    def blendshape_names(self) -> tuple[str, ...]:
        return BLENDSHAPES if self.face else ()


class PoseTracker:
    """Everyone in a sequence of images (or in single photos with `static_image=True`).

    >>> with PoseTracker() as tracker:                                   # doctest: +SKIP
    ...     main, people = tracker.track_people(bgr_image, t=0.0)
    """

    def __init__(self, settings: CaptureSettings = CaptureSettings(), static_image: bool = False):
        self.settings = settings
        self._marks = Landmarkers(settings.people, settings.hands, settings.face, video=not static_image,
                                  tiles=settings.tiles)
        self._ids = Tracks()
        self._main: int | None = None
        self._filters: dict[int, OneEuroFilter] = {}
        self._roots: dict[int, np.ndarray] = {}   # last camera-space translation per person
        self._last_ms = -1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        self._marks.close()

    def _detect(self, bgr: np.ndarray, t: float):
        import cv2
        ms = max(int(round(1000 * t)), self._last_ms + 1)  # VIDEO mode wants strictly increasing times
        self._last_ms = ms
        return self._marks.detect(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), ms)

    def landmarks(self, bgr: np.ndarray, t: float = 0.0):
        """(world (33, 3), image (33, 2), visibility (33,)) of the best-seen body in a BGR uint8 image, or
        None without a person."""
        bodies, _, _ = self._detect(bgr, t)
        if not bodies:
            return None
        return bodies[0].world, bodies[0].image, bodies[0].visibility

    def track(self, bgr: np.ndarray, t: float) -> Skeleton:
        """The main person's Kinect-20 skeleton in a BGR image taken at time `t` seconds (all untracked
        without a person)."""
        return self.track_people(bgr, t)[0]

    def track_people(self, bgr: np.ndarray, t: float) -> tuple[Skeleton, tuple[PersonFrame, ...]]:
        """Everyone in a BGR image taken at `t` seconds: the main person's skeleton (`people.main_person`; all
        untracked while they are out of view) and each person seen, by increasing id, with their hands and
        face."""
        bodies, hands, faces = self._detect(bgr, t)
        h, w = bgr.shape[:2]
        px = np.array([w, h], dtype=np.float64)
        centres = np.array([b.image[list(_TORSO)].mean(axis=0) * px for b in bodies]).reshape(-1, 2)
        sizes = np.array([_extent(b.image * px) for b in bodies])
        ids, self._ids = assign_ids(self._ids, centres, np.maximum(sizes, 1.0), t, self.settings.memory)
        self._main = main_person(self._main, self._ids, ids, centres, (w / 2, h / 2))
        live = {k.id for k in self._ids.tracks}
        for pid in set(self._filters) - live:
            del self._filters[pid]
        for pid in set(self._roots) - live:
            del self._roots[pid]
        skeletons = [self._place(int(pid), b, w, h, t) for pid, b in zip(ids, bodies)]
        hand_of = _hands_to_people(bodies, hands, px)
        face_of = _faces_to_people(bodies, faces, px)
        people = []
        for k, (pid, body, skeleton) in enumerate(zip(ids, bodies, skeletons)):
            marks = None
            if self.settings.hands:
                marks = np.full((2, 21, 3), np.nan)
                for side in (0, 1):
                    if (k, side) in hand_of:
                        marks[side] = self._hand_in_take(hand_of[k, side], body, skeleton, side, int(pid))
            face = face_of[k].blendshapes if k in face_of else None
            people.append(PersonFrame(int(pid), skeleton, marks, face))
        people.sort(key=lambda p: p.id)
        seen = [p for p in people if p.id == self._main]
        main = seen[0].skeleton if seen else Skeleton(KINECT20, np.full((len(KINECT20.joints), 3), np.nan),
                                                      np.zeros(len(KINECT20.joints), dtype=bool))
        return main, tuple(people)

    def _root(self, pid: int, body: Body, w: int, h: int) -> np.ndarray:
        root = root_translation(body.world, body.image, body.visibility >= self.settings.visibility, w, h,
                                self.settings.fov_degrees)
        if root is not None:
            self._roots[pid] = root
        return self._roots.get(pid, np.array([0.0, 0.0, self.settings.default_depth]))

    def _place(self, pid: int, body: Body, w: int, h: int, t: float) -> Skeleton:
        positions, tracked = kinect_from_mediapipe(body.world, body.visibility, self.settings.visibility)
        positions = (positions + self._root(pid, body, w, h)) @ FLIP.T
        positions[~tracked] = np.nan
        if self.settings.smooth:
            if pid not in self._filters:
                self._filters[pid] = OneEuroFilter(self.settings.min_cutoff, self.settings.beta)
            positions = self._filters[pid](positions, t)
        return Skeleton(KINECT20, positions, np.isfinite(positions).all(axis=1))

    def _hand_in_take(self, hand: Hand, body: Body, skeleton: Skeleton, side: int, pid: int) -> np.ndarray:
        """The hand's landmarks in the take's frame, its wrist at the body's (the tracked Kinect wrist, else
        the body's own wrist landmark however visible)."""
        joint = KINECT20.index("WristLeft" if side == 0 else "WristRight")
        if skeleton.tracked[joint]:
            wrist = skeleton.positions[joint]
        else:
            root = self._roots.get(pid, np.array([0.0, 0.0, self.settings.default_depth]))
            wrist = FLIP @ (body.world[_WRISTS[side]] + root)
        return (hand.world - hand.world[0]) @ FLIP.T + wrist


def _extent(points: np.ndarray) -> float:
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def _hands_to_people(bodies: list[Body], hands: list[Hand], px: np.ndarray) -> dict:
    """(body index, side 0 left / 1 right) -> hand: the assignment with the least summed distance from each
    hand's wrist to a body's wrist, a match no farther than the hand's own size."""
    if not bodies or not hands:
        return {}
    from scipy.optimize import linear_sum_assignment
    slots = [(k, side) for k in range(len(bodies)) for side in (0, 1)]
    wrists = np.array([bodies[k].image[_WRISTS[side]] * px for k, side in slots])
    starts = np.array([d.image[0] * px for d in hands])
    scale = np.array([max(_extent(d.image * px), 1.0) for d in hands])
    cost = np.linalg.norm(starts[:, None] - wrists[None], axis=2) / scale[:, None]
    rows, cols = linear_sum_assignment(cost)
    return {slots[c]: hands[r] for r, c in zip(rows, cols) if cost[r, c] <= 1.0}


def _faces_to_people(bodies: list[Body], faces: list[Face], px: np.ndarray) -> dict:
    """Body index -> face: the assignment with the least summed distance between the face's nose tip
    (landmark 1) and the body's nose (landmark 0), a match no farther than half the face's size."""
    if not bodies or not faces:
        return {}
    from scipy.optimize import linear_sum_assignment
    noses = np.array([b.image[0] * px for b in bodies])
    tips = np.array([f.image[1] * px for f in faces])
    scale = np.array([max(_extent(f.image * px), 1.0) for f in faces])
    cost = np.linalg.norm(tips[:, None] - noses[None], axis=2) / scale[:, None]
    rows, cols = linear_sum_assignment(cost)
    return {c: faces[r] for r, c in zip(rows, cols) if cost[r, c] <= 0.5}


def photo_people(path: str | os.PathLike, settings: CaptureSettings = CaptureSettings()) -> tuple[PersonFrame, ...]:
    """Everyone in a photo (ids 0, 1, ... best seen first), with hands and faces. Raises BadMotionError if
    the file is missing or unreadable, or nobody is found."""
    import cv2
    path = os.fspath(path)
    if not os.path.exists(path):
        raise BadMotionError(f"{path}: no such file")
    bgr = cv2.imread(path)
    if bgr is None:
        raise BadMotionError(f"{path}: cannot read the image")
    with PoseTracker(settings, static_image=True) as tracker:
        _, people = tracker.track_people(bgr, 0.0)
    if not people:
        raise BadMotionError(f"{path}: no person found in the image")
    return people


def capture_image(path: str | os.PathLike, settings: CaptureSettings = CaptureSettings()) -> Skeleton:
    """The skeleton of the (best-seen) person in a photo. Raises BadMotionError if unreadable or nobody is found."""
    return photo_people(path, settings)[0].skeleton


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
                  max_frames: int | None = None, progress: bool = False, every: int = 1) -> Take:
    """Track every `every`-th frame of a video file into a `Take` (at the video's frame rate / `every`),
    with everyone seen, their hands and faces.

    Frames without a person are kept (all joints untracked) so timing stays true. `max_frames` counts
    tracked frames.

    Raises
    ------
    BadMotionError
        The file is missing or not a video, has no frames, or shows no person in any frame.
    BadModelError
        A tracking model is missing or corrupted.
    """
    import cv2
    path = os.fspath(path)
    if not (isinstance(every, int) and every >= 1):
        raise BadSettingsError(f"every must be a whole number of frames >= 1, got {every!r}")
    if not os.path.exists(path):
        raise BadMotionError(f"{path}: no such file")
    cap = _open(path, path)
    fps = cap.get(cv2.CAP_PROP_FPS)
    fps = fps if np.isfinite(fps) and 1.0 <= fps <= 1000.0 else 30.0
    total = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) or None
    total = None if total is None else -(-total // every)
    if max_frames is not None:
        total = min(total or max_frames, max_frames)
    main: list[Skeleton] = []
    crowd: list[tuple[PersonFrame, ...]] = []
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=total, unit="frame", desc="tracking", leave=False, disable=None)  # terminals only
    try:
        with PoseTracker(settings) as tracker:
            k = 0
            while max_frames is None or len(main) < max_frames:
                ok, bgr = cap.read()
                if not ok:
                    break
                k += 1
                if (k - 1) % every:
                    continue
                skeleton, people = tracker.track_people(bgr, (k - 1) / fps)
                main.append(skeleton)
                crowd.append(people)
                if bar is not None:
                    bar.update(1)
    finally:
        cap.release()
        if bar is not None:
            bar.close()
    if not main:
        raise BadMotionError(f"{path}: the video has no readable frames")
    take = crowd_take(main, crowd, fps / every, path, settings.blendshape_names)
    if not take.tracked.any():
        raise BadMotionError(f"{path}: no person found in any of the {len(main)} frames")
    return take


def capture_camera(index: int | str, on_frame, settings: CaptureSettings = CaptureSettings(),
                   seconds: float | None = None, max_frames: int | None = None) -> int:
    """Track a webcam until Ctrl-C, `seconds` or `max_frames`, calling `on_frame(skeleton, t, people)` per
    frame with the main person's skeleton, `t` the wall-clock seconds since the start, and everyone seen
    (`PersonFrame`s by id).

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
                skeleton, people = tracker.track_people(bgr, t)
                on_frame(skeleton, t, people)
                count += 1
    except KeyboardInterrupt:
        pass  # Ctrl-C ends a recording; what was captured so far is kept
    finally:
        cap.release()
    return count
