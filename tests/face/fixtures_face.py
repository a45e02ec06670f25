"""A face video for tests: the shared portrait panned and rolled (a moving head for the tracker)."""
from __future__ import annotations

import shutil
import subprocess


def pan_video(source, target, seconds: float = 1.0) -> None:
    """The portrait panned sideways and rolled ±14° over `seconds` at 30 fps, 320x240 (y4m or mp4)."""
    assert shutil.which("ffmpeg"), "ffmpeg is needed (make setup installs it)"
    motion = ("scale=-2:520,pad=560:520:(ow-iw)/2:0,rotate='0.25*sin(2*PI*t/{s})':fillcolor=black,"
              "crop=320:240:120+40*sin(2*PI*t/{s}):30,format=yuv420p").format(s=seconds)
    codec = ["-f", "yuv4mpegpipe"] if str(target).endswith(".y4m") else ["-c:v", "libx264"]
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-loop", "1", "-i", str(source), "-t", str(seconds),
                    "-r", "30", "-vf", motion, *codec, str(target)], check=True, timeout=120)
