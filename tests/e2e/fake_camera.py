"""What Chromium's fake camera plays (--use-file-for-fake-video-capture): a .y4m file, made with ffmpeg from
a video or a still image."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path


def y4m(source: Path, target: Path, seconds: float | None = None, width: int | None = None) -> Path:
    """`source` (a video, or an image shown for `seconds`) as a 30 fps 4:2:0 .y4m of even size; `width` crops
    it to its middle that many pixels wide (a narrower camera's view of the same scene)."""
    assert shutil.which("ffmpeg"), "ffmpeg is needed (make setup installs it)"
    still = ["-loop", "1", "-t", str(seconds)] if seconds is not None else []
    crop = f"crop={width}:ih," if width else ""
    subprocess.run(["ffmpeg", "-v", "error", "-y", *still, "-i", str(source), "-r", "30",
                    "-vf", crop + "scale=trunc(iw/2)*2:trunc(ih/2)*2", "-pix_fmt", "yuv420p", "-f", "yuv4mpegpipe",
                    str(target)], check=True, timeout=120)
    return target
