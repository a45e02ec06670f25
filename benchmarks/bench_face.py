"""Face reconstruction (Algorithm 2): ms per frame of `reconstruct` on MediaPipe landmarks of the shared photos.

Prints one JSON object per line: {"bench": "face", ...} for the reconstruction (target ≤ 2 ms: alignment,
template-depth back-projection, five caricature morphs, chin anchor) and {"bench": "face_tracking", ...}
for MediaPipe Face Mesh itself in Python (for scale; the studio tracks in the page). Landmarks are tracked
once; the reconstruction is timed over many repeats of each photo's landmarks, median per frame.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import cv2
import numpy as np

from kinetre.face.caricature import morph_targets
from kinetre.face.landmarks import FaceTracker
from kinetre.face.reconstruct import reconstruct

os.environ.setdefault("GLOG_minloglevel", "2")
FACES = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "images" / "face"


def main(repeats: int = 400) -> None:
    images = [cv2.imread(str(p)) for p in sorted(FACES.glob("*")) if p.suffix in (".jpg", ".png")]
    morphs, weights = morph_targets(), np.array([0.5, 0.2, 0.3, 0.1, 0.4])
    track_ms, times = [], []
    with FaceTracker(static_image=True) as tracker:
        for image in images:
            t0 = time.perf_counter()
            lm = tracker.track(image)
            track_ms.append((time.perf_counter() - t0) * 1e3)
            h, w = image.shape[:2]
            for depth in (lm, lm[:, :2]):
                samples = []
                for _ in range(repeats if depth.shape[1] == 3 else repeats // 8):
                    t0 = time.perf_counter()
                    reconstruct(depth, w, h, morphs=morphs, weights=weights, turn=True)
                    samples.append(time.perf_counter() - t0)
                times.append((depth.shape[1], float(np.median(samples)) * 1e3))
    ms3 = float(np.mean([t for d, t in times if d == 3]))
    ms2 = float(np.mean([t for d, t in times if d == 2]))
    print(json.dumps({"bench": "face", "ms_per_frame": round(ms3, 4), "ms_per_frame_2d_landmarks": round(ms2, 4),
                      "target_ms": 2.0, "vertices": 468, "faces": len(images)}))
    print(json.dumps({"bench": "face_tracking", "ms_per_image_python_mediapipe": round(float(np.median(track_ms)), 2),
                      "note": "static-image mode (detector + landmarks each image)"}))


if __name__ == "__main__":
    main()
