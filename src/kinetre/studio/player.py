"""A server-side capture client that plays recorded motion (a BVH take) on its own skeleton channel.

It is the sample motion that keeps the page alive before any camera is granted: it publishes frames
exactly like a webcam page does (on `skeleton_subject(client)`); the scene tells them apart only by name
(`protocol.sends_mocap`: its mocap is not cleaned as a camera's is).
A motion file the user uploads (BVH, glTF, VRM Animation, a Kinetre take) plays the same way (`read_motion`).
"""
from __future__ import annotations

import asyncio
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BadMotionError, KinetreError
from ..skeleton.models import Skeleton
from .channels import Channels, Frame, now_ms
from .meshes import data_path
from .protocol import SAMPLE_CLIENT, SkeletonFrame, skeleton_json
from .subjects import skeleton_subject

# motion files a user may upload to play instead of the sample (a single-file glTF: .glb or embedded .gltf)
PLAYABLE = (".bvh", ".vrma", ".glb", ".gltf", ".kinetre.jsonl")


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
        while True:
            if self.playing:  # frames and fps change when the user loads another motion
                index = int((loop.time() - start) * self.fps)
                self.publish(index, now_ms())
            await asyncio.sleep(1.0 / self.fps)


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


def read_motion(name: str, data: bytes) -> tuple[list[Skeleton], float]:
    """An uploaded motion file (`PLAYABLE`) as the looping frames of a human skeleton (Kinect-20, travel
    removed) and their rate.

    Raises
    ------
    BadMotionError
        An unknown format, a file that does not read, a skeleton that is not a humanoid.
    """
    from ..avatar.bonemap import kinect_take
    from ..motion.source import load_take
    base = Path(name).name or "motion"
    if not base.lower().endswith(PLAYABLE):
        raise BadMotionError(f"{base}: not a motion file the studio plays (expected one of {', '.join(PLAYABLE)})")
    with tempfile.TemporaryDirectory(prefix="kinetre-motion-") as tmp:
        path = Path(tmp) / base
        path.write_bytes(data)
        try:
            take = kinect_take(load_take(str(path)))
        except KinetreError as exc:  # the user's file by its name, not the temporary copy's path
            raise BadMotionError(str(exc).replace(str(path), base)) from None
    frames = [take.frame(i) for i in range(len(take))]
    return decimate(in_place(frames), float(take.fps))
