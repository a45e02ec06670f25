"""The studio's channels over a NATS server, so capture pages, viewers and the scene can run on many machines.

`NatsChannels` offers the embedded `Hub`'s interface (`publish`, `subscribe` handing out latest-wins
`Subscription`s) and maps the studio's subjects into one room on the wire:

    studio subject                 NATS subject
    kinetre.skeleton.<user>   ↔    kinetre.<room>.skeleton.<user>     a capture client's frames
    kinetre.transforms.<id>   ↔    kinetre.<room>.transforms.<id>     each mesh's node matrices
    kinetre.state             ↔    kinetre.<room>.state               the scene's state (also its heartbeat)
    kinetre.client.<user>     ↔    kinetre.<room>.client.<user>       replies to one client
    kinetre.command.<user>    ↔    kinetre.<room>.command.<user>      a client's commands to a remote scene

Every message is a 16-byte envelope (u64 sequence number, f64 capture timestamp in ms, little-endian)
followed by the payload, so the sequence and capture time travel end to end without NATS headers.
Access is per room (*ours*): the NATS user is the room's name and its password the room's token, or else
the room is a NATS nkey user (an Ed25519 key pair: the server keeps the public key, studios and scenes
prove they hold the seed by signing the server's nonce; `room_nkey`, `nkey=`), and the server's per-user
permissions (`server_config`) confine that user to `kinetre.<room>.>`; request inboxes live inside the
room too, so a reply never crosses rooms.

Live subjects (skeletons, transforms, state) are latest-wins at the subscriber (a slow reader sees the
newest frame of each subject), and a frame older than the newest one delivered on its subject (smaller
sequence number and capture time) is dropped as late. Publishers send every frame, so a gap in a
subject's sequence numbers at the receiver is a frame lost on the way (`BusCounters.gaps`). Frames
published while the server is unreachable are dropped by policy (counted), never queued for replay.

Delivery and publishing skip nats-py's extra event-loop hops through its internals (natspatch.py, checked
against the nats-py versions it names; `start` refuses others).
"""
from __future__ import annotations

import asyncio
import logging
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import KinetreError
from .channels import Frame, Subscription, subject_matches
from .natspatch import ReadNow, Resumed, check_nats_version, subscribe_direct, write_pub
from .subjects import LIVE_KINDS, NAMESPACE, kind

log = logging.getLogger("kinetre.network")

ENVELOPE = struct.Struct("<Qd")  # seq, capture timestamp (ms)
ROOM_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_")


class NetworkError(KinetreError):
    """The NATS server is unreachable, refused our credentials, or refused a subject."""


def check_room(room: str) -> str:
    """A room name is one subject token: letters, digits, '-' and '_'."""
    if not room or not set(room) <= ROOM_CHARS or len(room) > 64:
        raise NetworkError(f"room name {room!r}: use 1-64 letters, digits, '-' or '_'")
    return room


def pack(frame: Frame) -> bytes:
    return ENVELOPE.pack(frame.seq & 0xFFFFFFFFFFFFFFFF, frame.t) + frame.data


def unpack(subject: str, payload: bytes) -> Frame | None:
    """The Frame inside a NATS message, or None when it has no envelope (a foreign publisher)."""
    if len(payload) < ENVELOPE.size:
        return None
    seq, t = ENVELOPE.unpack_from(payload)
    return Frame(subject, seq, t, payload[ENVELOPE.size:])


def room_nkey(seed_file: str | Path) -> str:
    """Make a room's nkey: a new user seed written to `seed_file` (readable by its owner only: it is the
    room's secret, for its studios and scene, `--nkey FILE`); returns the public key for `server_config`."""
    import nkeys
    seed = nkeys.encode_seed(os.urandom(32), nkeys.PREFIX_BYTE_USER)
    try:
        fd = os.open(seed_file, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    except OSError as exc:
        raise NetworkError(f"{seed_file}: cannot write the nkey seed ({exc.strerror})") from None
    with os.fdopen(fd, "wb") as f:
        f.write(seed + b"\n")
    return nkeys.from_seed(bytearray(seed)).public_key.decode()


def nkey_public(seed_file: str | Path) -> str:
    """The public key of the user nkey seed in `seed_file`; NetworkError naming the file otherwise."""
    import nkeys
    try:
        seed = bytearray(Path(seed_file).read_bytes().strip())
    except OSError as exc:
        raise NetworkError(f"{seed_file}: cannot read the nkey seed ({exc.strerror})") from None
    try:
        public = nkeys.from_seed(seed).public_key.decode()
    except (nkeys.NkeysError, ValueError):
        raise NetworkError(f"{seed_file}: not an nkey seed (one line starting with 'SU', as room_nkey "
                           "or `nk -gen user` write it)") from None
    if not public.startswith("U"):
        raise NetworkError(f"{seed_file}: an nkey seed, but not a user's (its line must start with 'SU')")
    return public


def is_nkey_user(key: str) -> bool:
    """A user's public nkey ('U' and 55 more base32 characters), as `room_nkey` returns."""
    return len(key) == 56 and key[0] == "U" and set(key) <= set("ABCDEFGHIJKLMNOPQRSTUVWXYZ234567")


def server_config(rooms: dict[str, str], port: int, host: str = "127.0.0.1", max_payload: int = 1 << 20) -> str:
    """A nats-server configuration with one user per room, confined to that room's subjects.

    `rooms` maps room name → its token (the password of a user named after the room) or its public nkey
    (`room_nkey`: the user is that key). Pass the text to `nats-server -c FILE`.
    """
    users = []
    for room, token in rooms.items():
        check_room(room)
        if not token or '"' in token or "\\" in token:
            raise NetworkError(f"room {room!r}: the token must be non-empty, without quotes or backslashes")
        allow = f'["{NAMESPACE}{room}.>"]'
        who = f'nkey: "{token}"' if is_nkey_user(token) else f'user: "{room}", password: "{token}"'
        users.append(f'    {{{who}, '
                     f'permissions: {{publish: {{allow: {allow}}}, subscribe: {{allow: {allow}}}}}}}')
    return (f"listen: {host}:{port}\nmax_payload: {max_payload}\n"
            "authorization {\n  users = [\n" + ",\n".join(users) + "\n  ]\n}\n")


@dataclass
class BusCounters:
    published: int = 0
    written: int = 0  # of those, written to the socket in the publisher's call (`natspatch.write_pub`)
    offline: int = 0  # frames published while the server was unreachable (dropped by policy)
    received: int = 0
    late: int = 0  # frames older than the newest delivered on their subject (dropped by policy)
    gaps: int = 0  # sequence numbers never delivered on live subjects (lost on the way, or a publisher restart)
    reconnects: int = 0
    errors: list[str] = field(default_factory=list)


class NatsChannels:
    """`Hub`'s interface over a NATS connection for one room.

    Usable before `start` (frames published then are dropped as offline, subscriptions wait for the
    connection), so a studio can be built synchronously and connect inside its event loop.
    """

    def __init__(self, room: str = "main"):
        self.room = check_room(room)
        self.nc = None
        self.url = ""
        self.prefix = f"{NAMESPACE}{room}."
        self.counters = BusCounters()
        self._subs: dict[str, object] = {}  # wire pattern → nats subscription (or the task creating it)
        self._local: dict[str, list[Subscription]] = {}  # wire pattern → our subscriptions
        self._newest: dict[str, tuple[int, float]] = {}  # subject → (seq, t) last delivered
        self._finishing: set[asyncio.Task] = set()  # publishes that had to wait for the connection's flusher
        self._plain: dict[str, bool] = {}  # wire subject → fit for a PUB line as it is
        # studio subjects nobody waits for: their frames are left to nats-py's flusher, which writes all that
        # is pending in one go (fewer writes and fewer wake-ups of nats-server and subscribers)
        self.batched: frozenset[str] = frozenset()

    @classmethod
    async def connect(cls, url: str, room: str = "main", token: str | None = None, name: str = "kinetre",
                      timeout: float = 5.0, nkey: str | Path | None = None) -> "NatsChannels":
        channels = cls(room)
        await channels.start(url, token, name, timeout, nkey)
        return channels

    async def start(self, url: str, token: str | None = None, name: str = "kinetre", timeout: float = 5.0,
                    nkey: str | Path | None = None) -> None:
        """Connect as the room's user: with the room's nkey seed file `nkey` if given, else its `token`;
        raises NetworkError (with the reason) when refused or unreachable."""
        check_nats_version()  # the fast paths rely on nats-py internals (natspatch.py)
        import nats
        import nats.errors
        room = self.room
        counters = self.counters

        async def error_cb(exc):
            text = str(exc) or type(exc).__name__
            counters.errors[:] = counters.errors[-99:] + [text]
            log.debug("NATS %s: %s", url, text)

        async def reconnected_cb():
            counters.reconnects += 1
            ReadNow.install(self.nc)  # the new connection's reader

        auth = {"user": room, "password": token} if token else {}
        if nkey:
            nkey_public(nkey)  # a missing or malformed file is named now, not as a failed handshake
            auth = {"nkeys_seed": str(nkey)}
        try:
            # a first connection that does not retry, so a refusal comes back as a clear error at once
            probe = await asyncio.wait_for(nats.connect(
                servers=[url], error_cb=error_cb, allow_reconnect=False, max_reconnect_attempts=0, connect_timeout=2, **auth),
                timeout)
            await probe.close()
            nc = await asyncio.wait_for(nats.connect(
                servers=[url], name=name, error_cb=error_cb, reconnected_cb=reconnected_cb,
                # a live studio resumes fast after a server restart and never gives up
                reconnect_time_wait=0.2, max_reconnect_attempts=-1, connect_timeout=2,
                allow_reconnect=True, ping_interval=5, max_outstanding_pings=2,
                inbox_prefix=f"{NAMESPACE}{room}._INBOX", **auth), timeout)
        except (nats.errors.NoServersError, OSError, asyncio.TimeoutError):
            raise NetworkError(f"{url}: no NATS server answers there (is nats-server running?)") from None
        except nats.errors.Error as exc:
            reason = str(exc) or type(exc).__name__
            if "authorization" in reason.lower() and nkey:
                reason = (f"room {room!r} was refused: the nkey in {nkey} is not the room's (the server lists "
                          "each room's public key)")
            elif "authorization" in reason.lower():
                reason = (f"room {room!r} was refused: {'wrong' if token else 'missing'} token "
                          "(the NATS user is the room's name, its password the room's token)")
            raise NetworkError(f"{url}: {reason}") from None
        self.nc, self.url = nc, url
        ReadNow.install(nc)
        for wire in list(self._local):
            self._subs[wire] = asyncio.get_running_loop().create_task(self._nats_subscribe(wire))

    # --- subjects ---------------------------------------------------------------------------------------
    def wire(self, subject: str) -> str:
        """"kinetre.transforms.1" → "kinetre.<room>.transforms.1"."""
        if not subject.startswith(NAMESPACE):
            raise NetworkError(f"subject {subject!r} is outside the studio's namespace")
        return self.prefix + subject[len(NAMESPACE):]

    def local(self, wire_subject: str) -> str:
        return NAMESPACE + wire_subject[len(self.prefix):]

    # --- publishing -------------------------------------------------------------------------------------
    def publish(self, frame: Frame) -> None:
        """Hand the frame to the connection now, in the caller's own call (no task of ours in between).

        When nothing is waiting in nats-py's pending buffer, the PUB command is written to the socket here
        (`natspatch.write_pub`), unless its subject is in `batched`. Otherwise it goes through nats-py's
        `publish`, a coroutine that, while connected, does not suspend: it appends the command to the pending buffer and
        wakes the connection's flusher task, which writes everything pending in one go. So it is run here to
        completion synchronously; only when it does suspend (the pending buffer is over its `pending_size` and
        it waits for the flusher) is the rest left to a task, the command being queued already, so order is
        kept either way.
        """
        if self.nc is None or not self.nc.is_connected:
            self.counters.offline += 1
            return
        subject = self.wire(frame.subject)
        payload = pack(frame)
        plain = self._plain.get(subject)
        if plain is None:  # a subject that cannot be one PUB line goes to nats-py, which refuses it
            plain = self._plain[subject] = not any(c in subject for c in " \t\r\n")
        if plain and frame.subject not in self.batched and write_pub(self.nc, subject, payload):
            self.counters.published += 1
            self.counters.written += 1
            return
        call = self.nc.publish(subject, payload)
        try:
            waiting = call.send(None)
        except StopIteration:
            self.counters.published += 1
            return
        except Exception as exc:  # closed or reconnecting: live data is dropped, not replayed
            self.counters.offline += 1
            log.debug("publish on %s failed: %s", subject, exc)
            return
        self.counters.published += 1
        self._finishing.add(asyncio.get_running_loop().create_task(self._finish(Resumed(call, waiting), subject)))

    async def _finish(self, call, subject: str) -> None:
        try:
            await call
        except Exception as exc:
            log.debug("publish on %s failed: %s", subject, exc)
        finally:
            self._finishing.discard(asyncio.current_task())

    # --- subscribing ------------------------------------------------------------------------------------
    def subscribe(self, *patterns: str, urgent: tuple[str, ...] = ()) -> Subscription:
        sub = Subscription(self, patterns + tuple(urgent), tuple(urgent))
        for pattern in sub.patterns:
            self._added(sub, pattern)
        return sub

    def _added(self, sub: Subscription, pattern: str) -> None:
        wire = self.wire(pattern)
        self._local.setdefault(wire, []).append(sub)
        if wire not in self._subs and self.nc is not None:
            self._subs[wire] = asyncio.get_running_loop().create_task(self._nats_subscribe(wire))

    async def _nats_subscribe(self, wire: str) -> None:
        def deliver(msg) -> None:
            frame = unpack(self.local(msg.subject), msg.data)
            if frame is None:
                return
            self.counters.received += 1
            if kind(frame.subject) in LIVE_KINDS:
                newest = self._newest.get(frame.subject)
                if newest is not None and frame.seq <= newest[0] and frame.t <= newest[1]:
                    self.counters.late += 1
                    return
                if newest is not None and frame.seq > newest[0] + 1:
                    self.counters.gaps += frame.seq - newest[0] - 1
                self._newest[frame.subject] = (frame.seq, frame.t)
            for sub in self._local.get(wire, ()):
                sub._offer(frame)

        self._subs[wire] = await subscribe_direct(self.nc, wire, deliver)

    async def ready(self, timeout: float = 5.0) -> None:
        """Wait until every subscription is registered with the server; raises NetworkError if one was refused."""
        tasks = [t for t in self._subs.values() if isinstance(t, asyncio.Task)]
        if tasks:
            await asyncio.gather(*tasks)
        errors = len(self.counters.errors)
        try:
            await self.nc.flush(timeout)
        except Exception as exc:
            raise NetworkError(f"the NATS server did not answer: {exc or type(exc).__name__}") from None
        await asyncio.sleep(0.05)  # a permissions error arrives right after the PONG
        refused = [e for e in self.counters.errors[errors:] if "permissions" in e.lower()]
        if refused:
            raise NetworkError(f"room {self.room!r}: {refused[0]}")

    def _remove(self, sub: Subscription) -> None:
        for wire, subs in list(self._local.items()):
            if sub in subs:
                subs.remove(sub)
            if not subs:
                del self._local[wire]
                nats_sub = self._subs.pop(wire, None)
                if nats_sub is not None and not isinstance(nats_sub, asyncio.Task):
                    asyncio.get_running_loop().create_task(self._unsubscribe(nats_sub))

    @staticmethod
    async def _unsubscribe(nats_sub) -> None:
        try:
            await nats_sub.unsubscribe()
        except Exception:  # the connection is closing anyway
            pass

    # --- request/reply (commands that need an answer) ---------------------------------------------------
    async def request(self, subject: str, data: bytes, timeout: float = 5.0) -> bytes:
        """One request on a studio subject, answered by whoever serves it (raises NetworkError on silence)."""
        import nats.errors
        try:
            msg = await self.nc.request(self.wire(subject), data, timeout=timeout)
        except (nats.errors.TimeoutError, nats.errors.NoRespondersError):
            raise NetworkError(f"nobody answered on {subject} in room {self.room!r} (is the scene running?)") \
                from None
        return msg.data

    async def serve(self, subject: str, handler) -> None:
        """Answer requests on a studio subject with `await handler(data) -> bytes`."""
        async def answer(msg) -> None:
            try:
                reply = await handler(msg.data)
            except Exception as exc:  # the requester gets the reason, the server keeps serving
                reply = b"\x00" + f"{type(exc).__name__}: {exc}".encode()
            if msg.reply:
                await self.nc.publish(msg.reply, reply)

        self._subs[self.wire(subject)] = await self.nc.subscribe(self.wire(subject), cb=answer)

    def deliver_local(self, frame: Frame) -> None:
        """Offer a frame to this process's subscribers only (e.g. the gateway's "scene lost" state)."""
        for wire, subs in self._local.items():
            if subject_matches(wire, self.wire(frame.subject)):
                for sub in subs:
                    sub._offer(frame)

    async def listen(self, pattern: str, handler) -> None:
        """`await handler(frame)` for every message on `pattern`, in order (commands: none may be merged)."""
        async def deliver(msg) -> None:
            frame = unpack(self.local(msg.subject), msg.data)
            if frame is not None:
                try:
                    await handler(frame)
                except Exception:
                    log.exception("handling %s", frame.subject)

        self._subs[self.wire(pattern)] = await self.nc.subscribe(self.wire(pattern), cb=deliver)

    @property
    def connected(self) -> bool:
        return self.nc is not None and bool(self.nc.is_connected)

    async def close(self) -> None:
        if self.nc is None:
            return
        try:
            await self.nc.drain()
        except Exception:
            await self.nc.close()


async def probe_nats(url: str, room: str, token: str | None, nkey: str | None = None) -> None:
    """Connect to the room once and leave; raises NetworkError with the reason."""
    bus = await NatsChannels.connect(url, room, token, name="kinetre-probe", nkey=nkey)
    await bus.close()
