"""Faster paths through nats-py's internals: delivery in the connection's reader, writes in the caller's call.

nats-py hands every message to its subscribers one event-loop iteration late (a task per callback
subscription, and a reader task that awaits its StreamReader), and writes every publish one iteration
late (its flusher task). On a busy studio each hop waits behind whatever else is ready then: a few ms at
the tail for every transform block and skeleton frame. The pieces here skip those hops while keeping
nats-py's order and limits:

- `subscribe_direct`: a subscription's queue replaced by one that delivers as the reader parses;
- `ReadNow`: the connection's bytes parsed in the socket's own callback when nats-py's reader is idle;
- `write_pub`: a PUB written straight to the socket when nothing of nats-py's is pending;
- `Resumed`: a nats-py coroutine run synchronously up to its first suspension, then finished in a task.

They use private attributes of nats-py (`Subscription._pending_queue`, `_pending_size`, the client's `_ps`,
`_transport._io_reader`/`_io_writer`, `_status`, `_pending_data_size`, `_max_payload`,
`_process_op_err`) and were checked against nats-py CHECKED_VERSIONS; `check_nats_version` refuses any
other version, so an upgrade is a deliberate step (re-read those internals, run tests/studio/test_natsbus.py,
then add the version). Each piece still falls back to nats-py's own path when an attribute is missing.
"""
from __future__ import annotations

import asyncio
import logging
from collections import deque

from ..errors import KinetreError

log = logging.getLogger("kinetre.network")

CHECKED_VERSIONS = ("2.16.0",)


class NatsVersionError(KinetreError):
    """The installed nats-py is not one whose internals this module was checked against."""


def check_nats_version(installed: str | None = None) -> str:
    """The installed nats-py version (or `installed`), if it is one of CHECKED_VERSIONS; else NatsVersionError."""
    if installed is None:
        from importlib.metadata import PackageNotFoundError, version
        try:
            installed = version("nats-py")
        except PackageNotFoundError:
            raise NatsVersionError("nats-py is not installed: pip install "
                                   f"nats-py=={CHECKED_VERSIONS[-1]}") from None
    if installed not in CHECKED_VERSIONS:
        raise NatsVersionError(
            f"nats-py {installed} is installed, but the studio's NATS fast paths (kinetre/studio/natspatch.py) "
            f"were checked against nats-py {', '.join(CHECKED_VERSIONS)} only: "
            f"pip install nats-py=={CHECKED_VERSIONS[-1]}")
    return installed


class Resumed:
    """An awaitable that goes on with a coroutine which already ran up to its first suspension (`waiting`,
    the future it yielded): `await Resumed(coro, waiting)` ends as `await coro` would have."""

    def __init__(self, coro, waiting):
        self.coro, self.waiting = coro, waiting

    def __await__(self):
        value = self.waiting
        while True:
            try:
                sent = yield value
            except BaseException as exc:  # e.g. cancelled: passed on into the coroutine
                try:
                    value = self.coro.throw(exc)
                except StopIteration as stop:
                    return stop.value
                continue
            try:
                value = self.coro.send(sent)
            except StopIteration as stop:
                return stop.value


class DirectDelivery(asyncio.Queue):
    """A nats-py subscription's message queue that hands each message on as the connection's reader parses
    it, instead of keeping it for a task of the subscription's own (one event-loop iteration later)."""

    def __init__(self, sub, take):
        super().__init__()
        self.sub, self.take = sub, take

    def put_nowait(self, msg) -> None:
        if hasattr(self.sub, "_pending_size"):  # counted as pending by the reader just before
            self.sub._pending_size -= len(msg.data)
        try:
            self.take(msg)
        except Exception:  # one bad message must not stop the connection's reader
            log.exception("delivering %s", msg.subject)


async def subscribe_direct(nc, subject: str, take):
    """A nats-py subscription whose messages reach `take(msg)` (a plain function) in the connection's reader.

    nats-py gives each callback subscription a task that awaits the subscription's queue, so every message
    would wait one more event-loop iteration, behind everything else ready then; a subscription without a
    callback has only the queue (`Subscription._pending_queue`, filled by the reader with `put_nowait`),
    which is replaced here by one that delivers at once. A nats-py without that queue gets an ordinary
    callback subscription.
    """
    sub = await nc.subscribe(subject)
    old = getattr(sub, "_pending_queue", None)
    if not isinstance(old, asyncio.Queue):
        await sub.unsubscribe()

        async def call(msg) -> None:
            take(msg)
        return await nc.subscribe(subject, cb=call)
    sub._pending_queue = DirectDelivery(sub, take)
    while not old.empty():  # none normally: the server has not seen the SUB yet
        sub._pending_queue.put_nowait(old.get_nowait())
    return sub


class ReadNow:
    """Hands the bytes of a nats-py connection to its protocol parser in the socket's own callback.

    nats-py's reader task awaits its StreamReader: every message waits one more event-loop iteration,
    behind whatever else is ready then (on a busy gateway, milliseconds at the tail for a transform block).
    Installed as the StreamReader's `feed_data`, this parses the data at once whenever nats-py's reader is
    idle (waiting for data with nothing buffered), so the order is kept; otherwise, and for EOF and errors,
    the data goes to the StreamReader as before. A parse that must wait (nats-py awaiting a full queue, or
    an error handler) finishes in a task, and data arriving meanwhile is parsed after it. Without the
    transport's `_io_reader` or the client's `_ps`, nothing is installed.
    """

    def __init__(self, nc, reader: asyncio.StreamReader):
        self.nc, self.reader = nc, reader
        self.feed = reader.feed_data  # the StreamReader's own
        self.behind: deque | None = None  # data that arrived while a parse was waiting
        self.parsed = 0  # reads parsed in the socket's callback
        reader.feed_data = self

    @classmethod
    def install(cls, nc) -> bool:
        reader = getattr(getattr(nc, "_transport", None), "_io_reader", None)
        if not isinstance(reader, asyncio.StreamReader) or not hasattr(nc, "_ps"):
            return False
        if not isinstance(reader.__dict__.get("feed_data"), cls):
            cls(nc, reader)
        return True

    def __call__(self, data) -> None:
        if self.behind is not None:
            self.behind.append(bytes(data))
            return
        r = self.reader
        waiter = getattr(r, "_waiter", None)
        if not data or r._buffer or waiter is None or waiter.done() or r.at_eof() or r.exception() is not None:
            self.feed(data)  # nats-py's reader is busy or has data of its own to parse first
            return
        self._parse(data)

    def _parse(self, data) -> None:
        self.parsed += 1
        call = self.nc._ps.parse(data)
        try:
            waiting = call.send(None)
        except StopIteration:
            return
        except Exception as exc:
            self._failed(exc)
            return
        self.behind = deque()
        asyncio.get_running_loop().create_task(self._finish(Resumed(call, waiting)))

    async def _finish(self, call) -> None:
        try:
            await call
            while self.behind:
                await self.nc._ps.parse(self.behind.popleft())
        except Exception as exc:
            self._failed(exc)
        finally:
            self.behind = None

    def _failed(self, exc: Exception) -> None:
        """As nats-py's reader would: a protocol error closes the connection (it then reconnects)."""
        import nats.errors
        self.reader.feed_data = self.feed
        log.debug("NATS parse failed: %s", exc)
        error = exc if isinstance(exc, nats.errors.ProtocolError) else nats.errors.ProtocolError()
        asyncio.get_running_loop().create_task(self.nc._process_op_err(error))


def write_pub(nc, subject: str, payload: bytes) -> bool:
    """Write one PUB straight to the connection's socket when that keeps nats-py's order and limits.

    Only while connected (not draining or reconnecting: then nats-py's own buffering applies), with its
    pending buffer empty (everything published before is already in the socket's hands, so the order holds),
    a plain TCP/TLS stream (nats-py's `_io_writer`; its WebSocket transport queues writes in a task of its
    own) with nothing buffered in the transport (else nats-py's flusher waits for it to drain), and a payload
    within the server's limit (nats-py raises on a larger one). False: publish through `nc.publish`.
    """
    try:
        writer = nc._transport._io_writer
        if (nc._status != nc.CONNECTED or nc._pending_data_size or len(payload) > nc._max_payload
                or writer is None or writer.transport.is_closing() or writer.transport.get_write_buffer_size()):
            return False
        writer.write(b"PUB %b %d\r\n%b\r\n" % (subject.encode(), len(payload), payload))  # NATS's PUB
    except AttributeError:
        return False
    nc.stats["out_msgs"] += 1
    nc.stats["out_bytes"] += len(payload)
    return True
