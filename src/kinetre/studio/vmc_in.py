"""`kinetre studio --vmc-listen PORT`: VMC performers (XR Animator, VSeeFace, a phone app) as studio users.

Each performer (told apart by the address its packets come from) becomes a user "vmc<n>" whose skeleton
frames go on its own subject, exactly as a webcam page's do, so the scene, the other pages and the avatars
see one more person; its face (`/VMC/Ext/Blend/Val`, as blendshapes) rides on them as a page's does, so the
pages' avatars show its expressions, takes record it and VMC out passes it on. A performer possesses the
mesh when it starts, as the sample motion does (fitted to the mesh, taking over from the sample; a live user
who already possesses keeps it and the two add up).
"""
from __future__ import annotations

import asyncio
import logging

import numpy as np

from ..skeleton.models import Skeleton
from ..vmc.receive import VmcListener
from .channels import Channels, Frame, now_ms
from .protocol import SkeletonFrame, skeleton_json, vmc_client
from .subjects import skeleton_subject

log = logging.getLogger("kinetre.studio")
RETRY_S = 0.5  # a possession refused (no frame in the scene yet) is tried again after this long


class VmcUsers:
    """A VMC listener whose performers publish skeleton frames and possess through `command(client, msg)`
    (the studio's one command dispatch, which returns the failure or None: {"type": "fit"} then
    {"type": "possess"})."""

    def __init__(self, hub: Channels, command, host: str = "127.0.0.1", port: int = 39539):
        self.hub, self.command = hub, command
        self.listener = VmcListener(self.receive, host, port)
        self.clients: dict = {}            # performer address -> client name
        self.seq: dict[str, int] = {}
        self.possessed: set[str] = set()
        self.trying: dict[str, float] = {}  # client -> loop time of its last possession attempt
        self.tasks: set[asyncio.Task] = set()

    async def start(self) -> None:
        await self.listener.start()

    @property
    def port(self) -> int:
        return self.listener.port

    def client(self, address) -> str:
        if address not in self.clients:
            self.clients[address] = vmc_client(len(self.clients) + 1)
        return self.clients[address]

    def receive(self, address, skeleton: Skeleton, blendshapes: np.ndarray | None = None) -> None:
        client = self.client(address)
        seq = self.seq[client] = self.seq.get(client, 0) + 1
        t = now_ms()
        self.hub.publish(Frame(skeleton_subject(client), seq, t,
                               skeleton_json(client, seq, t, skeleton, blendshapes=blendshapes),
                               SkeletonFrame(seq, t, skeleton, blendshapes=blendshapes)))
        loop = asyncio.get_running_loop()
        if client not in self.possessed and loop.time() - self.trying.get(client, -RETRY_S) >= RETRY_S:
            self.trying[client] = loop.time()
            task = loop.create_task(self._possess(client))
            self.tasks.add(task)
            task.add_done_callback(self.tasks.discard)

    async def _possess(self, client: str) -> None:
        await asyncio.sleep(0.05)  # the scene takes the first frame from the bus first
        for msg in ({"type": "fit"}, {"type": "possess"}):
            failed = await self.command(client, msg)
            if failed is not None:  # answered and, if the server's fault, logged by the dispatch
                log.info("VMC performer %s cannot possess yet: %s", client, failed)
                return
        self.possessed.add(client)
        log.info("VMC performer %s possesses the mesh", client)

    def close(self) -> None:
        self.listener.close()
        for task in self.tasks:
            task.cancel()
