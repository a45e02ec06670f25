"""The scene's users and their frames: where a frame enters the scene.

A user is one capture source (a page's webcam, one person of several in its camera, the sample-motion
player, a VMC performer). Each keeps only its newest frame: frames are merged latest-wins, so a slow solve
lowers the frame rate instead of building a queue, and a late or duplicate frame is dropped, never
reordered.
"""
from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.signal  # noqa: F401  cleaning tunes its filter with it: loaded with the server, not mid-frame

from ...motion.cleanup import CleanupSettings, LiveCleaner, RoomFloor
from ...motion.hands import SIDES, HandPuppet
from ...motion.quality import LiveMeter
from ...skeleton.models import HAND21, KINECT20, Skeleton
from ...skeleton.subsets import subset_mask
from ..channels import Frame
from ..placement import Placement
from ..protocol import ProtocolError, SkeletonFrame, parse_frame, parse_message, sends_mocap
from ..subjects import last_token

# how long a possession waits for the user's first tracked frame: a page sends "possess" right after its
# first detection, and on a busy host that frame may still be on its way through the hub
FIRST_FRAME_S = 3.0


async def arrival(ready: Callable[[], bool], wait: float = FIRST_FRAME_S) -> None:
    """Return once `ready()` holds or `wait` seconds have passed (the caller then checks it again)."""
    deadline = time.monotonic() + wait
    while not ready() and time.monotonic() < deadline:
        await asyncio.sleep(0.05)


def parse(data: bytes) -> SkeletonFrame | None:
    """A skeleton frame from the bus, or None when it does not parse (it came through a server that
    validated it, so only a foreign publisher in the room can send one)."""
    try:
        return parse_frame(parse_message(data))
    except ProtocolError:
        return None


@dataclass
class User:
    """One capture source and its newest frame."""

    client: str
    parsed: Skeleton | None = None  # world frame, newest parsed (see `latest`)
    parsed_hands: np.ndarray | None = None  # (2, 21, 3) of the newest parsed frame (see `hands`)
    parsed_blendshapes: np.ndarray | None = None  # (52,) of the newest parsed frame (see `blendshapes`)
    raw: bytes | None = None  # a newer frame not parsed yet (a user who does not drive the solve)
    seq: int = -1
    t: float = 0.0
    frames: int = 0
    used: int = -1  # seq of the frame the last solve used
    arrived: float = 0.0  # monotonic time the newest frame arrived (s)
    period: float = 0.0  # running mean of the time between its frames (s)
    bind: Skeleton | None = None  # mesh frame, the pose at possession (None = not possessing)
    mesh: int | None = None  # the id of the mesh it possesses
    subset: str | list | None = None
    stand: tuple | None = None  # (R, t): where a joint map's source stands, x -> R x + t (see meshes.stand_in)
    hand: str | None = None  # "left" or "right" while a hand possesses (a hand puppet), None for the body
    puppet: HandPuppet | None = None  # that hand put inside the mesh, fitted at possession
    cleanup: CleanupSettings | None = None  # how its body frames are cleaned while it possesses (None: as sent)
    room: RoomFloor | None = None  # the room's floor, which its held feet stand on
    cleaner: LiveCleaner | None = None  # cleaning its frames since it possessed (None: not possessing)
    meter: LiveMeter | None = None  # its live motion quality, as tracked and as cleaned

    @property
    def latest(self) -> Skeleton | None:
        """The newest frame (world frame). Parsed on first use: of the many users sending frames only the
        possessing ones drive the solve; the others' frames are needed only when one fits or possesses. A
        frame that does not parse leaves the last good one."""
        self._parse_raw()
        return self.parsed

    @property
    def hands(self) -> np.ndarray | None:
        """(2, 21, 3) the left and right hand landmarks of the newest frame (world frame, metres, +Y up, the
        wrist at the skeleton's wrist; NaN rows for a hand not seen), or None when the user sends no hands."""
        self._parse_raw()
        return self.parsed_hands

    def seen_hand(self, side: str) -> np.ndarray | None:
        """(21, 3) hand `side` ("left", "right") of the newest frame, or None when it is not seen there."""
        marks = self.hands
        if marks is None or not np.isfinite(marks[SIDES.index(side)]).all():
            return None
        return marks[SIDES.index(side)]

    @property
    def tracking(self) -> bool:
        """Whether the newest frame tracks any joint."""
        return self.latest is not None and bool(self.latest.tracked.any())

    @property
    def blendshapes(self) -> np.ndarray | None:
        """(52,) the face blendshape weights of the newest frame (`skeleton.mediapipe.BLENDSHAPES` order), or
        None without a face."""
        self._parse_raw()
        return self.parsed_blendshapes

    @property
    def possessing(self) -> bool:
        return self.bind is not None

    def take_frame(self, frame: SkeletonFrame, metered: bool = True) -> None:
        """Keep `frame` as the newest parsed frame, its body cleaned first when the user has a cleaner
        (kinetre.motion.cleanup: causal, no frame of delay) and measured by its meter (unless not `metered`:
        a frame parsed late, after others went unread, would break the meter's time series)."""
        skeleton = frame.skeleton
        # only a possessing user's frames drive a solve: only they are cleaned and metered, so a room of
        # onlookers costs the server no filtering (a cleaner takes every frame, in order, from possession on)
        if self.bind is not None and self.cleanup is not None and self.cleaner is None:
            self.cleaner = LiveCleaner(KINECT20, self.cleanup, room=self.room)
        if self.bind is not None and self.meter is not None and (metered or self.cleaner is not None) and \
                skeleton.model is KINECT20:
            seconds = frame.t / 1000.0  # frames carry milliseconds
            seen = np.where(skeleton.tracked[:, None], skeleton.positions, np.nan)
            if self.cleaner is None:
                self.meter.add(seen, seen, seconds)
            else:
                cleaned = self.cleaner(seen, seconds)
                held, hold = self.cleaner.held()
                joints = list(self.cleaner.joints or ())
                self.meter.add(seen, cleaned, seconds, held,
                               np.linalg.norm(cleaned[joints] - hold, axis=1) if joints else None)
                skeleton = Skeleton(skeleton.model, np.where(np.isfinite(cleaned), cleaned, skeleton.positions),
                                    skeleton.tracked)
        self.parsed, self.parsed_hands, self.parsed_blendshapes, self.raw = \
            skeleton, frame.hands, frame.blendshapes, None

    @property
    def cleaning(self) -> list[str]:
        """What cleans its body frames before the solve: "smoothing", "contact", both or neither."""
        c = self.cleanup
        return [] if c is None else [k for k, on in (("smoothing", c.smooth), ("contact", c.contact)) if on]

    def _parse_raw(self) -> None:
        if self.raw is not None:
            raw, self.raw = self.raw, None
            frame = parse(raw)
            if frame is not None:
                self.take_frame(frame, metered=False)

    def let_go(self) -> None:
        """Possess nothing (the subset stays: it is the user's choice for the next possession)."""
        self.bind = self.mesh = self.stand = self.hand = self.puppet = None
        self.cleaner = None  # the next possession cleans afresh: its filter and holds start from its frames

    def placed(self, skeleton: Skeleton) -> Skeleton:
        """The frame moved to where the user's joint-map source stands (unchanged without one)."""
        return skeleton if self.stand is None else skeleton.transformed(1.0, *self.stand)

    def hand_frame(self) -> Skeleton:
        """The newest frame of the possessing hand as a `HAND21` skeleton (world frame; untracked when the
        hand is not seen)."""
        marks = self.hands
        side = np.full((21, 3), np.nan) if marks is None else marks[SIDES.index(self.hand)]
        return Skeleton.from_positions(HAND21, side)

    def driving(self, placement: Placement) -> Skeleton:
        """The frame that drives the mesh, in its own frame: the possessing hand put inside it, or the body
        where the mesh stands in the room (`placement`), moved to its joint-map source's place, masked."""
        if self.hand is not None:
            return self.masked(self.puppet.place(self.hand_frame()))
        return self.masked(placement.to_local(self.placed(self.latest)))

    def masked(self, skeleton: Skeleton) -> Skeleton:
        """Joints outside the user's subset count as untracked, so they neither attach nor pull."""
        if self.subset is None:
            return skeleton
        return Skeleton(skeleton.model, skeleton.positions, skeleton.tracked & subset_mask(skeleton.model,
                                                                                           self.subset))


class Users(dict):
    """The scene's users by client, and what became of the frames that reached it.

    Before the solve, a camera user's body frames are smoothed and their feet held with `clean` (the studio's
    default; `kinetre studio --raw` turns it off); a mocap user's (`protocol.sends_mocap`: the sample player,
    VMC performers) only have their feet held, with `contact` (`--contact`), as `kinetre animate` treats mocap.
    All feet are held on one floor for the room (`room`). Every user's motion is metered (`User.meter`)."""

    def __init__(self, clean: bool = True, contact: bool = False):
        super().__init__()
        self.clean, self.contact = clean, contact
        self.room = RoomFloor()
        self.late = 0  # skeleton frames older than the user's newest (dropped)
        self.superseded = 0  # possessing users' frames replaced by a newer one before any solve used them
        self.frames_in = 0  # skeleton frames that reached the scene

    def user(self, client: str) -> User:
        """User `client`, added on first mention."""
        if client not in self:
            self[client] = User(client, meter=LiveMeter(), cleanup=self.cleanup(client), room=self.room)
        return self[client]

    def cleanup(self, client: str) -> CleanupSettings | None:
        """How user `client`'s body frames are cleaned, None when they are used as sent."""
        if sends_mocap(client):
            return CleanupSettings(smooth=False) if self.contact else None
        return CleanupSettings() if self.clean else None

    def applied(self, client: str) -> dict | None:
        """What cleans user `client`'s frames, for a take's `applied` header (None: as sent)."""
        settings = self.cleanup(client)
        return None if settings is None else LiveCleaner(KINECT20, settings).describe()

    def possessing(self, mesh_id: int) -> list[str]:
        """The clients possessing mesh `mesh_id`, in the order they came."""
        return [c for c, u in self.items() if u.bind is not None and u.mesh == mesh_id]

    def receive(self, frame: Frame) -> User | None:
        """Take a skeleton frame from the hub (already validated by the server that published it) as its
        user's newest; the user, or None when the frame was late, a duplicate or unreadable."""
        user = self.user(last_token(frame.subject))
        parsed = None
        if frame.value is not None:
            parsed = frame.value  # decoded by the publisher in this process
        elif user.bind is not None:
            parsed = parse(frame.data)
            if parsed is None:
                return None
        # without a parsed frame, the bus envelope's seq and t; the JSON is parsed when needed (User.latest)
        seq, t = (frame.seq, frame.t) if parsed is None else (parsed.seq, parsed.t)
        if seq <= user.seq and user.frames:
            self.late += 1
            return None  # late or duplicate frame: skip, never reorder
        if user.bind is not None and user.frames and user.used != user.seq:
            self.superseded += 1  # merged latest-wins: the solve only ever takes the newest
        if parsed is None:
            user.raw = frame.data
        else:
            user.take_frame(parsed)
        user.seq, user.t = seq, t
        user.frames += 1
        arrived = time.monotonic()
        if user.arrived:
            gap = min(arrived - user.arrived, 1.0)
            user.period = gap if not user.period else user.period + 0.1 * (gap - user.period)
        user.arrived = arrived
        return user
