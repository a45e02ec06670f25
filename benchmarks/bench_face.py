"""Face reconstruction (Algorithm 2): ms per frame of `reconstruct` on MediaPipe landmarks of the shared photos.

Prints one JSON object per line: {"bench": "face", ...} for the reconstruction (target ≤ 2 ms: alignment,
template-depth back-projection, five caricature morphs, chin anchor) and {"bench": "face_tracking", ...}
for MediaPipe Face Mesh itself in Python (for scale; the studio tracks in the page). Landmarks are tracked
once; the reconstruction is timed over many repeats of each photo's landmarks, median per frame.
{"bench": "face_page", ...}: landmarks per second in the studio page (Face Mesh in wasm + Algorithm 2 +
the puppet) in headless Chromium on SwiftShader, the fake camera playing the portrait panned (10 s);
skipped with a note when the page is not built or node/chromium are missing.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from kinetre.face.caricature import morph_targets
from kinetre.face.landmarks import FaceTracker
from kinetre.face.reconstruct import reconstruct

os.environ.setdefault("GLOG_minloglevel", "2")
ROOT = Path(__file__).resolve().parents[1]
FACES = ROOT / ".." / "shared" / "data" / "images" / "face"
sys.path.insert(0, str(ROOT / "tests"))


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


def page_rate(seconds: float = 10.0) -> None:
    from face.fixtures_face import pan_video
    from studio.conftest import start_server
    if not (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file() or not shutil.which("node"):
        print(json.dumps({"bench": "face_page", "skipped": "page not built or node missing"}))
        return
    proc, url = start_server(nodes=64, sample_motion=False)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            video = Path(tmp) / "pan.y4m"
            pan_video((FACES / "face_frontal_portrait.jpg").resolve(), video, seconds=3.0)
            config = {"scenario": "rate", "url": url, "video": str(video), "seconds": seconds, "artifacts": tmp}
            out = subprocess.run(["node", str(ROOT / "tests" / "e2e" / "driver_face.mjs"), json.dumps(config)],
                                 capture_output=True, text=True, timeout=400, cwd=ROOT)
        result = json.loads(out.stdout.strip().splitlines()[-1])
        if not result.get("ok"):
            print(json.dumps({"bench": "face_page", "error": result.get("error", "")[:300]}))
            return
        r = result["rate"]
        print(json.dumps({"bench": "face_page", "landmarks_per_second": round(r["landmarksPerSecond"], 2),
                          "detect_ms": r["detectMs"], "renderer": "SwiftShader (headless Chromium, --disable-gpu)",
                          "camera": "320x240 fake camera", "seconds": seconds}))
    finally:
        proc.terminate()
        proc.wait(10)


if __name__ == "__main__":
    main()
    page_rate()
