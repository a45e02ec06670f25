"""Publish/subscribe channels between capture clients, the scene and viewers.

Every capture client publishes its skeleton frames on its own subject, the scene publishes node
transforms on one subject, and any number of viewers subscribe. Subjects follow NATS syntax
(dot-separated tokens, `*` matches one token, `>` the rest) so that a NATS server can replace the
embedded `Hub` for many machines: a replacement implements the same two methods, `publish` and
`subscribe`, and hands out objects with the `Subscription` methods.

Delivery is *latest wins per subject* for live data: a subscriber that falls behind sees only the newest
frame of each subject, never a queue. Memory per subscription is bounded by the number of subjects it
matches. Replies to one client and commands (subjects.QUEUED_KINDS) are queued instead: every error
message must reach its page, every command its scene.

    >>> import asyncio
    >>> async def demo():
    ...     hub = Hub()
    ...     sub = hub.subscribe("kinetre.skeleton.*")
    ...     for seq in range(3):
    ...         hub.publish(Frame("kinetre.skeleton.a", seq, 0.0, b"x"))
    ...     return (await sub.next()).seq
    >>> asyncio.run(demo())
    2
"""
from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass, field
from typing import Any, Protocol

from .subjects import QUEUED_KINDS, kind


@dataclass(frozen=True)
class Frame:
    """One message on a subject.

    Attributes
    ----------
    subject : str
        e.g. "kinetre.skeleton.c3" or "kinetre.transforms.1".
    seq : int
        The publisher's sequence number (increasing per subject).
    t : float
        The publisher's timestamp in milliseconds (Unix epoch), carried end to end for latency.
    data : bytes
        The payload (JSON text or a binary transform block); the hub never looks inside.
    value : object, optional
        The payload already decoded, when publisher and subscriber share a process (the embedded
        hub); a network bus leaves it None and subscribers decode `data`.
    """

    subject: str
    seq: int
    t: float
    data: bytes
    value: Any = field(default=None, compare=False, repr=False)


def now_ms() -> float:
    """A frame timestamp: milliseconds since the Unix epoch."""
    return time.time() * 1000.0


def subject_matches(pattern: str, subject: str) -> bool:
    """NATS subject matching: `*` is one token, a trailing `>` is one or more tokens.

    >>> subject_matches("a.*.c", "a.b.c"), subject_matches("a.>", "a.b.c"), subject_matches("a.*", "a.b.c")
    (True, True, False)
    """
    p, s = pattern.split("."), subject.split(".")
    for i, token in enumerate(p):
        if token == ">":
            return len(s) > i
        if i >= len(s) or (token != "*" and token != s[i]):
            return False
    return len(p) == len(s)


class Subscription:
    """The receiving end of `Hub.subscribe`: a latest-wins slot per matching subject."""

    def __init__(self, hub: "Hub", patterns: tuple[str, ...], urgent: tuple[str, ...] = ()):
        self.patterns = patterns
        self.urgent = urgent
        self._hub = hub
        self._first: dict[object, Frame] = {}  # subjects matching `urgent`, delivered before the others
        self._latest: dict[object, Frame] = {}  # insertion order = order subjects became pending
        self._wakeup = asyncio.Event()
        self._is_urgent: dict[str, tuple[bool, bool]] = {}  # subject → (urgent, queued), matched once
        self._queued = 0
        self.skipped = 0  # frames replaced before they were read (how far a slow reader fell behind)
        self.closed = False
        # frame -> bool: takes a frame at once when nothing is pending (so order is kept), False declines
        # and the frame waits in its slot as usual (fanout.py: transform blocks written straight to a page)
        self.direct = None

    def _offer(self, frame: Frame) -> None:
        if self.direct is not None and not self._first and not self._latest and self.direct(frame):
            return
        mode = self._is_urgent.get(frame.subject)
        if mode is None:
            mode = self._is_urgent[frame.subject] = (any(subject_matches(p, frame.subject) for p in self.urgent),
                                                     kind(frame.subject) in QUEUED_KINDS)
        slots = self._first if mode[0] else self._latest
        if mode[1]:
            self._queued += 1
            slots[(frame.subject, self._queued)] = frame  # a key of its own: never replaced
        else:
            if frame.subject in slots:
                self.skipped += 1
                # keep the subject's place in line, replace its frame
            slots[frame.subject] = frame
        self._wakeup.set()

    def poll(self) -> Frame | None:
        """The oldest pending subject's newest frame (urgent subjects first), or None when nothing is pending."""
        slots = self._first or self._latest
        if not slots:
            return None
        frame = slots.pop(next(iter(slots)))
        if not self._first and not self._latest:
            self._wakeup.clear()
        return frame

    async def pending(self) -> bool:
        """Wait until a frame is pending, without taking it (`poll` takes it); False once closed."""
        while not self.closed and not (self._first or self._latest):
            self._wakeup.clear()
            await self._wakeup.wait()
        return not self.closed

    async def next(self, timeout: float | None = None) -> Frame | None:
        """Wait for the next frame (None on timeout or after `close`)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.closed:
            frame = self.poll()
            if frame is not None:
                return frame
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                return None
            try:
                await asyncio.wait_for(self._wakeup.wait(), remaining)
            except asyncio.TimeoutError:
                return None
        return None

    def add(self, pattern: str) -> None:
        """Also receive the subjects matching `pattern` from now on."""
        if pattern not in self.patterns:
            self.patterns += (pattern,)
            self._hub._added(self, pattern)

    def close(self) -> None:
        self.closed = True
        self._wakeup.set()
        self._hub._remove(self)


class Channels(Protocol):
    """What the studio needs from a message bus (the embedded `Hub`, or a NATS client adapter)."""

    def publish(self, frame: Frame) -> None: ...

    def subscribe(self, *patterns: str, urgent: tuple[str, ...] = ()) -> Subscription: ...


@dataclass
class Hub:
    """The in-process bus embedded in the studio server. Not thread-safe: use it from the event loop."""

    _subs: list[Subscription] = field(default_factory=list)
    _routes: dict[str, list[Subscription]] = field(default_factory=dict)  # subject → its subscribers
    published: int = 0

    def publish(self, frame: Frame) -> None:
        self.published += 1
        route = self._routes.get(frame.subject)
        if route is None:
            route = [sub for sub in self._subs if any(subject_matches(p, frame.subject) for p in sub.patterns)]
            self._routes[frame.subject] = route
        for sub in route:
            sub._offer(frame)

    def subscribe(self, *patterns: str, urgent: tuple[str, ...] = ()) -> Subscription:
        """One latest-wins subscription to every subject matching any of `patterns` or `urgent`.

        Frames on `urgent` subjects are delivered before any other pending frame (a viewer that is
        behind gets the node transforms before other users' skeletons).
        """
        sub = Subscription(self, patterns + tuple(urgent), tuple(urgent))
        self._subs.append(sub)
        self._routes.clear()
        return sub

    def _added(self, sub: Subscription, pattern: str) -> None:
        self._routes.clear()

    def _remove(self, sub: Subscription) -> None:
        if sub in self._subs:
            self._subs.remove(sub)
            self._routes.clear()
