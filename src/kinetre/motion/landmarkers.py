"""MediaPipe's Tasks landmarkers (body, hands, face) over an image and its square tiles.

The `.task` models are the studio page's (`kinetre.motion.models.model_path`), run through mediapipe
0.10.14's Tasks API: PoseLandmarker (up to `people` bodies), HandLandmarker (two hands a person) and
FaceLandmarker with its 52 blendshapes; faces may also be looked for without bodies (the face puppet's
tracker, `kinetre.face.landmarks`). In VIDEO mode each tile keeps its own landmarkers, since MediaPipe
follows what it found in the previous frame of the same stream. Detections from all tiles are brought to
whole-image coordinates and merged (`kinetre.motion.tiles`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BadMotionError
from ..skeleton.mediapipe import BLENDSHAPES
from .models import model_path
from .tiles import Tile, distinct, square_tiles


@dataclass(frozen=True, eq=False)
class Body:
    """One body: world (33, 3) metres, hip-centred, camera axes (x right, y down, z away); image (33, 2)
    normalised to the whole image; visibility (33,) in [0, 1]."""

    world: np.ndarray
    image: np.ndarray
    visibility: np.ndarray


@dataclass(frozen=True, eq=False)
class Hand:
    """One hand: world (21, 3) metres about the hand's centre, camera axes; image (21, 2) normalised to the
    whole image; score, MediaPipe's handedness confidence."""

    world: np.ndarray
    image: np.ndarray
    score: float


@dataclass(frozen=True, eq=False)
class Face:
    """One face: image (478, 2) normalised to the whole image (the first 468 on Face Mesh's canonical
    topology, then 10 iris points); depth (478,) MediaPipe's relative depth, smaller towards the camera, in
    units of the whole image's width (the scale of image x); blendshapes (52,) weights named `BLENDSHAPES`."""

    image: np.ndarray
    depth: np.ndarray
    blendshapes: np.ndarray


def _tasks():
    try:
        import mediapipe as mp
        from mediapipe.tasks.python import BaseOptions, vision
    except ImportError:
        raise BadMotionError("tracking needs MediaPipe: pip install 'kinetre[capture]' "
                             "(mediapipe==0.10.14)") from None
    return mp, BaseOptions, vision


class Landmarkers:
    """Bodies, hands and faces in RGB images, tile by tile.

    people : most bodies (and faces) looked for; hands : look for hands (two a person); face : look for faces;
    video : frames of one stream (VIDEO mode, timestamps increasing) rather than unrelated photos;
    tiles : also search overlapping square crops (`square_tiles`), for people small in a wide frame;
    bodies : look for bodies (False: faces or hands alone, without running the pose model).

    Raises BadModelError when a model file is missing or corrupted (naming `make models`).
    """

    def __init__(self, people: int = 4, hands: bool = True, face: bool = True, video: bool = True,
                 tiles: bool = True, bodies: bool = True):
        self.people, self.hands, self.face, self.video, self.tiles = int(people), hands, face, video, tiles
        self.bodies = bodies
        self._paths = {"pose": model_path("pose_landmarker_full.task") if bodies else None,
                       "hand": model_path("hand_landmarker.task") if hands else None,
                       "face": model_path("face_landmarker.task") if face else None}
        self._size = None
        self._open: list[tuple[Tile, dict]] = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        for _, marks in self._open:
            for m in marks.values():
                m.close()
        self._open = []

    def _landmarkers(self) -> dict:
        mp, BaseOptions, vision = _tasks()
        mode = vision.RunningMode.VIDEO if self.video else vision.RunningMode.IMAGE

        def base(kind):
            return BaseOptions(model_asset_path=str(self._paths[kind]))
        out = {}
        if self.bodies:
            out["pose"] = vision.PoseLandmarker.create_from_options(vision.PoseLandmarkerOptions(
                base_options=base("pose"), running_mode=mode, num_poses=self.people))
        if self.hands:
            out["hand"] = vision.HandLandmarker.create_from_options(vision.HandLandmarkerOptions(
                base_options=base("hand"), running_mode=mode, num_hands=2 * self.people))
        if self.face:
            out["face"] = vision.FaceLandmarker.create_from_options(vision.FaceLandmarkerOptions(
                base_options=base("face"), running_mode=mode, num_faces=self.people,
                output_face_blendshapes=True))
        return out

    def detect(self, rgb: np.ndarray, t_ms: int = 0) -> tuple[list[Body], list[Hand], list[Face]]:
        """Everyone in an (H, W, 3) uint8 RGB image; `t_ms` the frame's time in milliseconds (VIDEO mode:
        increasing from frame to frame). Each list holds distinct detections, best first."""
        mp, _, _ = _tasks()
        h, w = rgb.shape[:2]
        if self._size != (w, h):
            tiles = square_tiles(w, h) if self.tiles else square_tiles(w, h)[:1]
            if self.video or len(tiles) > len(self._open):
                self.close()      # a stream of another size starts afresh
                self._open = [(tile, self._landmarkers()) for tile in tiles]
            else:                 # photos carry no state from one to the next: the landmarkers are reused
                for _, marks in self._open[len(tiles):]:
                    for m in marks.values():
                        m.close()
                self._open = [(tile, marks) for tile, (_, marks) in zip(tiles, self._open)]
            self._size = (w, h)
        bodies, hands, faces = [], [], []
        for tile, marks in self._open:
            crop = np.ascontiguousarray(rgb[tile.y:tile.y + tile.height, tile.x:tile.x + tile.width])
            image = mp.Image(image_format=mp.ImageFormat.SRGB, data=crop)
            run = (lambda m: m.detect_for_video(image, int(t_ms))) if self.video else (lambda m: m.detect(image))
            if "pose" in marks:
                pose = run(marks["pose"])
                for marks_2d, marks_3d in zip(pose.pose_landmarks, pose.pose_world_landmarks):
                    bodies.append(Body(np.array([[p.x, p.y, p.z] for p in marks_3d]),
                                       tile.to_image(np.array([[p.x, p.y] for p in marks_2d]), w, h),
                                       np.array([p.visibility for p in marks_2d])))
            if "hand" in marks:
                found = run(marks["hand"])
                for marks_2d, marks_3d, side in zip(found.hand_landmarks, found.hand_world_landmarks,
                                                     found.handedness):
                    hands.append(Hand(np.array([[p.x, p.y, p.z] for p in marks_3d]),
                                      tile.to_image(np.array([[p.x, p.y] for p in marks_2d]), w, h),
                                      float(side[0].score)))
            if "face" in marks:
                found = run(marks["face"])
                for marks_2d, shapes in zip(found.face_landmarks, found.face_blendshapes):
                    weights = np.zeros(len(BLENDSHAPES))
                    for c in shapes:
                        weights[BLENDSHAPES.index(c.category_name)] = c.score
                    # z is normalised like x, by the tile's width: rescale it to the whole image's
                    faces.append(Face(tile.to_image(np.array([[p.x, p.y] for p in marks_2d]), w, h),
                                      np.array([p.z for p in marks_2d]) * tile.width / w, weights))
        px = np.array([w, h], dtype=np.float64)
        bodies = [bodies[i] for i in distinct([b.image * px for b in bodies],
                                              np.array([b.visibility.mean() for b in bodies]))][:self.people]
        hands = [hands[i] for i in distinct([d.image * px for d in hands], np.array([d.score for d in hands]))]
        # faces carry no confidence: the first found is kept, the whole image's before the tiles'
        faces = [faces[i] for i in distinct([f.image * px for f in faces], np.zeros(len(faces)))][:self.people]
        return bodies, hands, faces
