"""Tracking in the page: Debian's Chromium (SwiftShader, no GPU) with a video as its camera, MediaPipe Tasks
in the page's worker, the mesh possessed; one person (pose_1) and two people (two_people_pose_1, as the
front and back legs of Spot through examples/maps/two-people-horse.json), the two seen by a 480x360 camera (the
middle of the clip) and by a wide 640x360 one (the whole clip, whose squares are searched as well).

Prints JSON lines {"bench": "tracking_page", "people": N, ...}:
  detections_per_s    landmark results the worker delivered per second (pose, hands and face)
  render_fps          frames the page drew per second meanwhile (goal: >= 8 under SwiftShader)
  latency_p95_ms      camera frame captured -> node transforms of the solve that used it, on the page
  id_switches         ids seen beyond the people in view (goal: 0)
  seconds_to_find     from the tracker's start until everyone in view is tracked
  seconds_camera_to_first_tracked   from the Camera key until the first person's body is tracked (the
                      tracker's start-up included: what a user waits for)

`--query "?noshadows&notiles"` runs the page without its square search of wide frames (docs/tracking.md),
for comparison.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]
VIDEO = ROOT / ".." / "shared" / "data" / "video"
sys.path.insert(0, str(ROOT / "tests"))

from e2e.fake_camera import y4m  # noqa: E402
from e2e.node_driver import run_driver  # noqa: E402
from studio.conftest import start_server  # noqa: E402

SECONDS = 15


def size(video: Path) -> str:
    """A .y4m's frame size, "WxH", from its header ("YUV4MPEG2 W480 H360 ...")."""
    with video.open("rb") as f:
        fields = f.readline().split()
    return "x".join(next(v[1:].decode() for v in fields if v[:1] == k) for k in (b"W", b"H"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--query", default="?noshadows", help="the studio page's query string")
    parser.add_argument("--people", default="1,2", help="which cameras: 1, 2 or 1,2 (default)")
    args = parser.parse_args()
    query, wanted = args.query, {int(n) for n in args.people.split(",")}
    if not (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file():
        print(json.dumps({"bench": "tracking_page", "error": "the page is not built: make web"}))
        return
    with tempfile.TemporaryDirectory(prefix="kinetre-bench-") as folder:
        two = (VIDEO / "two_people_pose_1_640x360.mp4").resolve()
        cameras = [(1, (VIDEO / "pose_1_320x240_30fps.y4m").resolve()),
                   (2, y4m(two, Path(folder) / "two_480x360.y4m", width=480)),
                   (2, y4m(two, Path(folder) / "two_640x360.y4m"))]
        proc, url = start_server(nodes=128, sample_motion=False, timeout=600)  # slow to start on a busy machine
        try:
            for people, video in [(n, v) for n, v in cameras if n in wanted]:
                if people == 2:  # both possess: the front and back legs, as in the paper's horse
                    httpx.post(url + "/api/jointmap?name=two-people-horse.json",
                               content=(ROOT / "examples" / "maps" / "two-people-horse.json").read_bytes())
                r = run_driver("driver_people.mjs", {"scenario": "track", "url": url + "/", "query": query,
                                                     "video": str(video), "people": people, "seconds": SECONDS,
                                                     "artifacts": str(ROOT / "tests" / "e2e" / "artifacts")}, 300)
                p = r["perf"]
                view = size(video)
                print(json.dumps({"bench": "tracking_page", "people": people, "view": view, "camera": video.name,
                                  "query": query,
                                  "delegate": p["delegate"], "seconds": SECONDS, "possessing": r["possessing"],
                                  "detections_per_s": round(p["detectionsPerSecond"], 2),
                                  "render_fps": round(p["renderFps"], 1),
                                  "latency_p95_ms": None if p["latencyP95Ms"] is None else round(p["latencyP95Ms"]),
                                  "latency_median_ms": None if p["latencyMedianMs"] is None else round(p["latencyMedianMs"]),
                                  "worker_ms_per_detection": round(p["detectMs"], 1),
                                  "id_switches": p["idSwitches"],
                                  "seconds_to_find": round(r["secondsToFind"], 1),
                                  "seconds_camera_to_first_tracked": round(r["secondsCameraToFirstTracked"], 1)}),
                      flush=True)
        finally:
            proc.terminate()
            proc.wait(10)


if __name__ == "__main__":
    main()
