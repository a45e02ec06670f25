"""One page's connection: its skeleton frames in, the scene's transforms, state and replies out.

A page (or any WebSocket client) is a capture client and a viewer at once. What it sends: its own
skeleton frames (published on its skeleton subject for the scene), connection settings (`subscribe`,
`ack`, `stats`) handled here, and commands for the scene, handed to the `SceneHost`. What it gets: the
newest transform block and state (latest wins: a slow page never has a queue of stale frames), replies
meant for it, and, if it asked, the other users' skeletons.
"""
from __future__ import annotations

import asyncio
import json
from dataclasses import dataclass, field

from starlette.websockets import WebSocket, WebSocketDisconnect
from websockets.frames import Opcode

from .channels import Channels, Frame
from .fanout import Framing, raw_socket
from .host import SceneHost, answer_error, apply, reply
from .protocol import ProtocolError, parse_frame, parse_message, parse_person, person_client, with_client
from .subjects import SKELETON_PREFIX, SKELETONS, STATE, TRANSFORMS, client_subject, is_transforms, skeleton_subject


@dataclass
class ClientStats:
    received: int = 0
    malformed: int = 0
    last_seq: int = -1
    skeletons: bool = False  # forward other users' skeleton frames to this client
    window: int = 0  # flow control: at most this many messages sent and not yet acknowledged (0 = off)
    sent: int = 0
    acked: int = 0
    ack: asyncio.Event = field(default_factory=asyncio.Event)
    transforms_sent: int = 0
    transforms_skipped: int = 0  # scene frames this client never got: replaced by newer ones (latest wins)
    transforms_seq: dict = field(default_factory=dict)  # per transforms subject (one per mesh), the last seq


class Viewer:
    """The server's end of one WebSocket (`client`: the name the server gave it)."""

    def __init__(self, ws: WebSocket, client: str, hub: Channels, host: SceneHost, framing: Framing,
                 resume: str = ""):
        self.ws, self.client, self.hub, self.host, self.framing = ws, client, hub, host, framing
        self.resume = resume  # the token that lets this page come back as the same client (sessions.py)
        self.close_code: int | None = None  # how the connection ended (WebSocket close code)
        self.stats = ClientStats()
        self.sub = hub.subscribe(urgent=(TRANSFORMS, STATE, client_subject(client)))
        self._sending = False  # the send loop is handing a message to the server (see `run`'s `direct`)

    async def run(self) -> None:
        """Greet the page, then serve it until it disconnects (`close_code` then says how)."""
        ws, stats, host = self.ws, self.stats, self.host
        await ws.send_text(json.dumps({"type": "welcome", "client": self.client, "resume": self.resume,
                                       "channel": skeleton_subject(self.client)}))
        await ws.send_text(json.dumps(host.state()))
        blocks = host.transforms_blocks()  # none while a remote scene has not been heard yet
        for block in blocks:
            await ws.send_bytes(block)
        stats.transforms_sent = len(blocks)  # a count of every transform block the page got, these included
        stats.sent = 2 + len(blocks)
        raw = raw_socket(ws.scope)
        if raw is not None:
            def direct(frame: Frame) -> bool:
                """A transform block or the state, written in the publisher's call when the page can take it
                now and nothing sent before it is still on its way (so the page gets them in order)."""
                transforms = is_transforms(frame.subject)
                if not (transforms or frame.subject == STATE) or self._sending or not raw.ready() or (
                        stats.window and stats.sent - stats.acked >= stats.window):
                    return False  # send_loop delivers it (latest wins) once the page can take it
                if transforms:
                    self._count_transforms(frame)
                    raw.write(self.framing(frame.data))
                else:
                    stats.sent += 1
                    raw.write(self.framing(frame.data, Opcode.TEXT))
                return True
            self.sub.direct = direct
        sender = asyncio.get_running_loop().create_task(self._send_loop())
        try:
            while True:
                message = await ws.receive()
                if message["type"] == "websocket.disconnect":
                    self.close_code = message.get("code", 1000)
                    break
                data = message.get("text")
                if data is None:
                    data = message.get("bytes") or b""
                await self.receive(data)
        except WebSocketDisconnect as exc:
            self.close_code = exc.code
        finally:
            sender.cancel()
            self.sub.close()

    async def receive(self, text: str | bytes) -> None:
        """One message from the page; a malformed one is answered with an error, never fatal."""
        stats = self.stats
        try:
            msg = parse_message(text)
            kind = msg["type"]
            if kind == "skeleton":
                frame = parse_frame(msg)
                stats.received += 1
                stats.last_seq = frame.seq
                user = person_client(self.client, parse_person(msg))  # one of several people in its camera
                self.hub.publish(Frame(skeleton_subject(user), frame.seq, frame.t, with_client(text, user), frame))
            elif kind == "subscribe":
                stats.skeletons = bool(msg.get("skeletons"))
                if stats.skeletons:
                    self.sub.add(SKELETONS)  # only now: a watcher that never asks costs nothing per frame
                window = msg.get("window", 0)
                if not isinstance(window, int) or not 0 <= window <= 256:
                    raise ProtocolError(f"window must be an integer 0..256, got {window!r}")
                stats.window = window
                stats.ack.set()
            elif kind == "ack":
                received = msg.get("received")
                if not isinstance(received, int) or received < 0:
                    raise ProtocolError(f"ack needs 'received', a message count, got {received!r}")
                stats.acked = max(stats.acked, min(received, stats.sent))
                stats.ack.set()
            elif kind == "stats":
                reply(self.hub, self.client, {
                    "type": "stats", "client": self.client, "received": stats.received,
                    "malformed": stats.malformed, "last_seq": stats.last_seq,
                    "transforms_sent": stats.transforms_sent, "transforms_skipped": stats.transforms_skipped})
            else:
                failed = await apply(self.host, self.hub, self.client, msg,
                                     text.encode() if isinstance(text, str) else text)
                stats.malformed += isinstance(failed, ProtocolError)
        except Exception as exc:  # the client's mistake or the server's (logged): the connection goes on
            if isinstance(exc, ProtocolError):
                stats.malformed += 1
            answer_error(self.hub, self.client, exc)

    def _count_transforms(self, frame: Frame) -> None:
        stats = self.stats
        stats.sent += 1  # counted before any await: an ack may arrive before the send returns
        last = stats.transforms_seq.get(frame.subject, 0)
        if last and frame.seq > last + 1:
            stats.transforms_skipped += frame.seq - last - 1
        stats.transforms_seq[frame.subject], stats.transforms_sent = frame.seq, stats.transforms_sent + 1

    async def _send_loop(self) -> None:
        # One sender per connection: a slow viewer only ever has the newest frame per subject waiting.
        # With a window, it also never has more than `window` messages in the network buffers, which
        # would otherwise hold seconds of stale frames for a page whose main thread is busy.
        stats, ws = self.stats, self.ws
        own = "." + self.client
        while True:
            if not await self.sub.pending():
                return
            # checked once a message waits: while this loop waited, messages may have gone out directly
            if stats.window and stats.sent - stats.acked >= stats.window:
                stats.ack.clear()
                await stats.ack.wait()
                continue
            frame = self.sub.poll()
            if frame is None:
                continue
            skeleton = frame.subject.startswith(SKELETON_PREFIX)
            if skeleton and (not stats.skeletons or frame.subject.endswith(own)):
                continue  # other users' skeletons only for viewers that asked; a page draws its own
            self._sending = True
            try:
                if is_transforms(frame.subject):
                    self._count_transforms(frame)
                    await ws.send_bytes(frame.data)
                else:
                    stats.sent += 1  # counted before the await: an ack may arrive before the send returns
                    await ws.send_text(frame.data.decode())
            finally:
                self._sending = False
