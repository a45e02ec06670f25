"""A server-side capture client that plays recorded motion (a BVH take) on its own skeleton channel.

It is the sample motion that keeps the page alive before any camera is granted: it publishes frames
exactly like a webcam page does (on `skeleton_subject(client)`), so the scene cannot tell them apart.
"""
from __future__ import annotations

import asyncio
from dataclasses import dataclass

import numpy as np

from ..errors import KinetreError
from ..skeleton.models import Skeleton
from .channels import Channels, Frame, now_ms
from .meshes import data_path
from .protocol import SkeletonFrame, skeleton_json
from .subjects import skeleton_subject

SAMPLE_CLIENT = "sample"


def in_place(frames: list[Skeleton], root: int = 0) -> list[Skeleton]:
    """The frames with the root's horizontal travel removed (a walk on a treadmill), so a loop does not jump."""
    start = frames[0].positions[root, [0, 2]]
    out = []
    for f in frames:
        shift = np.zeros(3)
        if f.tracked[root]:
            shift[[0, 2]] = f.positions[root, [0, 2]] - start
        out.append(Skeleton(f.model, f.positions - shift, f.tracked))
    return out


@dataclass
class MotionPlayer:
    """Loops `frames` at `fps` on `skeleton_subject(client)` while `playing`.

    Attributes
    ----------
    hub : Channels
    frames : list of Skeleton (metres, +Y up)
    fps : float
        Playback rate of `frames`.
    client : str
        The channel's last token.
    """

    hub: Channels
    frames: list[Skeleton]
    fps: float
    client: str = SAMPLE_CLIENT
    playing: bool = True
    seq: int = 0

    @property
    def subject(self) -> str:
        return skeleton_subject(self.client)

    def publish(self, index: int, t: float) -> None:
        frame = self.frames[index % len(self.frames)]
        self.seq += 1
        payload = skeleton_json(self.client, self.seq, t, frame)
        self.hub.publish(Frame(self.subject, self.seq, t, payload, SkeletonFrame(self.seq, t, frame)))

    async def run(self) -> None:
        """Publish frames in real time (frames are skipped, not delayed, when the loop is late)."""
        loop = asyncio.get_running_loop()
        start = loop.time()
        period = 1.0 / self.fps
        while True:
            if self.playing:
                index = int((loop.time() - start) / period)
                self.publish(index, now_ms())
            await asyncio.sleep(period)


def decimate(frames: list[Skeleton], fps: float, target: float = 30.0) -> tuple[list[Skeleton], float]:
    """Every k-th frame so the rate is about `target` (a 120 fps BVH becomes 30 fps)."""
    step = max(1, int(round(fps / target)))
    return frames[::step], fps / step


def sample_player(hub: Channels) -> MotionPlayer | None:
    """The CMU walk (shipped in kinetre/data) as a looping capture client, or None if it cannot load."""
    try:
        from ..motion.bvh import load_bvh
        take = load_bvh(str(data_path("cmu_12_01_walk.bvh")))
        frames = [take.frame(i) for i in range(len(take))]
        fps = float(take.fps)
    except (ImportError, KinetreError):
        return None
    frames, fps = decimate(in_place(frames), fps)
    return MotionPlayer(hub, frames, fps, SAMPLE_CLIENT)
