"""`kinetre studio --vmc HOST:PORT`: every avatar in the studio sends its pose to a VMC receiver, live.

The server retargets each skeleton frame onto each avatar on the shelf (Algorithm 1, the same plan the page
retargets with) and sends the result as one VMC bundle (vmc/send.py). Like the page, an avatar follows one
source at a time: whoever drives it keeps it until silent for `STALE_S`, then any other user (a webcam, the
sample motion, a VMC performer) takes over. Avatar n sends to PORT + n − 1, so several avatars reach
several receivers (VSeeFace, Warudo... listen on one port each).
"""
from __future__ import annotations

import logging
import time

import numpy as np

from ..avatar.bonemap import kinect_from_openni
from ..avatar.retarget import RetargetState, retarget
from ..skeleton.models import Skeleton
from ..vmc.send import VmcSender, frame_bundle, vmc_frames
from .avatars import Shelf
from .channels import Channels
from .protocol import ProtocolError, parse_frame, parse_message
from .subjects import SKELETONS, last_token

log = logging.getLogger("kinetre.studio")
STALE_S = 1.0  # another source may drive once the current one has been silent this long (as the page)


class VmcOut:
    """Sends the shelf's avatars as VMC, one bundle per skeleton frame of the driving source."""

    def __init__(self, hub: Channels, shelf: Shelf, host: str, port: int, clock=time.monotonic):
        self.hub, self.shelf, self.host, self.port, self.clock = hub, shelf, host, port, clock
        self.source: str | None = None
        self.last = -np.inf
        self.start = clock()
        self.senders: dict[int, VmcSender] = {}
        self.states: dict[int, RetargetState] = {}
        self.sent = 0

    def target(self, avatar_id: int) -> tuple[str, int]:
        """The receiver avatar `avatar_id` sends to."""
        return self.host, self.port + avatar_id - 1

    def offer(self, client: str, skeleton: Skeleton) -> int:
        """One skeleton frame of `client`: sent for every avatar with a plan if `client` drives; returns the
        bundles sent."""
        now = self.clock()
        if client != self.source and self.source is not None and now - self.last < STALE_S:
            return 0
        if client != self.source:
            self.states.clear()                      # a new source starts from the bind pose
            self.source = client
        self.last = now
        positions, tracked = skeleton.positions[None], skeleton.tracked[None]
        if skeleton.model.name == "openni17":
            positions, tracked = kinect_from_openni(positions, tracked)
        elif skeleton.model.name != "kinect20":
            return 0
        count = 0
        for avatar_id, entry in list(self.shelf.avatars.items()):
            plan = entry.get("plan")
            if plan is None:
                continue
            state = self.states.setdefault(avatar_id, RetargetState())
            frames = vmc_frames(plan, entry["bonemap"], retarget(plan, positions, tracked, state))
            sender = self.senders.get(avatar_id)
            if sender is None:
                sender = self.senders[avatar_id] = VmcSender(*self.target(avatar_id))
            sender.send(frame_bundle(frames, 0, now - self.start))
            count += 1
        self.sent += count
        return count

    async def run(self) -> None:
        """Follow every user's skeleton frames until cancelled."""
        sub = self.hub.subscribe(SKELETONS)
        try:
            while True:
                frame = await sub.next()
                if frame is None:
                    return
                try:
                    skeleton = (frame.value if frame.value is not None else
                                parse_frame(parse_message(frame.data))).skeleton
                except ProtocolError:
                    continue
                self.offer(last_token(frame.subject), skeleton)
        finally:
            sub.close()
            self.close()

    def close(self) -> None:
        for sender in self.senders.values():
            sender.close()
        self.senders.clear()
