"""`kinetre studio --vmc HOST:PORT`: every avatar in the studio sends its pose to a VMC receiver, live.

The server retargets each skeleton frame onto each avatar on the shelf (Algorithm 1, the same plan the page
retargets with) and sends the result as one VMC bundle (vmc/send.py): the body, the finger bones of each hand
the frame carries (`avatar.retarget.retarget_fingers`; a hand out of view is not sent, so a receiver holds
its last pose) and the face's blendshapes as `/VMC/Ext/Blend/Val` (VRM 0.x presets and ARKit names). Like
the page, an avatar follows one source at a time: whoever drives it keeps it until silent for `STALE_S`, then
any other user (a webcam, the sample motion, a VMC performer) takes over. Avatar n sends to PORT + n − 1, so
several avatars reach several receivers (VSeeFace, Warudo... listen on one port each).
"""
from __future__ import annotations

import logging
import time

import numpy as np

from ..avatar.bonemap import kinect_from_openni
from ..avatar.fingers import FingerMap, map_fingers
from ..avatar.retarget import RetargetState, retarget, retarget_fingers
from ..skeleton.mediapipe import BLENDSHAPES
from ..skeleton.models import Skeleton
from ..vmc.send import VmcSender, blend_frames, frame_bundle, vmc_frames
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
        self.fingers: dict[int, tuple] = {}  # avatar id -> (its plan, the finger chains found with it)
        self.sent = 0

    def target(self, avatar_id: int) -> tuple[str, int]:
        """The receiver avatar `avatar_id` sends to."""
        return self.host, self.port + avatar_id - 1

    def offer(self, client: str, skeleton: Skeleton, hands: np.ndarray | None = None,
              blendshapes: np.ndarray | None = None) -> int:
        """One skeleton frame of `client`, with its hands ((2, 21, 3), NaN for a hand not seen) and face
        blendshapes ((52,), `BLENDSHAPES` order) when it has them: sent for every avatar with a plan if `client`
        drives; returns the bundles sent."""
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
        blend = None if blendshapes is None else blend_frames(BLENDSHAPES, blendshapes[None])[0]
        count = 0
        for avatar_id, entry in list(self.shelf.avatars.items()):
            plan = entry.get("plan")
            if plan is None:
                continue
            state = self.states.setdefault(avatar_id, RetargetState())
            motion = retarget(plan, positions, tracked, state)
            fingers = self.seen_fingers(avatar_id, entry, hands)
            if fingers:
                motion = retarget_fingers(entry["avatar"], plan, fingers, motion, hands[None])
            frames = vmc_frames(plan, entry["bonemap"], motion, fingers)
            sender = self.senders.get(avatar_id)
            if sender is None:
                sender = self.senders[avatar_id] = VmcSender(*self.target(avatar_id))
            sender.send(frame_bundle(frames, 0, now - self.start, blend))
            count += 1
        self.sent += count
        return count

    def seen_fingers(self, avatar_id: int, entry: dict, hands: np.ndarray | None) -> FingerMap | None:
        """The avatar's finger chains on the sides whose hand `hands` holds (None without any)."""
        if hands is None:
            return None
        plan, chains = self.fingers.get(avatar_id, (None, None))
        if plan is not entry["plan"]:                # found again once the avatar's map changes
            chains = map_fingers(entry["avatar"], entry["bonemap"])
            self.fingers[avatar_id] = (entry["plan"], chains)
        seen = np.isfinite(hands).all(axis=(1, 2))
        return FingerMap({key: chain for key, chain in chains.chains.items() if seen[key[0]]}) or None

    async def run(self) -> None:
        """Follow every user's skeleton frames until cancelled."""
        sub = self.hub.subscribe(SKELETONS)
        try:
            while True:
                frame = await sub.next()
                if frame is None:
                    return
                try:
                    parsed = frame.value if frame.value is not None else parse_frame(parse_message(frame.data))
                except ProtocolError:
                    continue
                self.offer(last_token(frame.subject), parsed.skeleton, parsed.hands, parsed.blendshapes)
        finally:
            sub.close()
            self.close()

    def close(self) -> None:
        for sender in self.senders.values():
            sender.close()
        self.senders.clear()
