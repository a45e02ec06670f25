"""Transform blocks written straight to the viewers' sockets, framed once per block.

Every solved frame goes to every connected page: a hundred pages at 40 Hz are thousands of WebSocket
messages a second. Through ASGI each send goes through Starlette's send wrappers, the server's WebSocket
protocol framing and a copy of the block for every page, plus a wake-up of that page's sender task, so one
publish kept the loop busy long enough for the frames of capture clients to wait behind it. Here the block
is framed once (an unmasked binary frame, RFC 6455 §5.2, by `websockets`) and, in the publisher's own call,
written to each page's transport that can take it now: no task wakes, a send is one `transport.write`
(figures: benchmarks/bench_network.py). The scene's state (a text frame, once a second and on every
change) goes the same way: sent through ASGI to a hundred pages, it held the loop for milliseconds.

This needs the server's connection object, which ASGI does not expose: `RawSockets` (middleware) puts
the server's `send` in the WebSocket's scope, and `raw_socket` accepts it only for uvicorn's sans-I/O
`websockets` protocol with no extension negotiated (permessage-deflate is off in `run_studio`).
Under any other server, or with an extension, pages get every message through ASGI as before.
"""
from __future__ import annotations

from websockets.frames import Frame, Opcode

SCOPE_KEY = "kinetre.send"


class RawSockets:
    """ASGI middleware: a WebSocket connection's scope carries the server's own `send` callable."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] == "websocket":
            scope = {**scope, SCOPE_KEY: send}
        await self.app(scope, receive, send)


class RawSocket:
    """A page's connection, written without ASGI (see the module docstring)."""

    def __init__(self, protocol):
        self._protocol = protocol

    def ready(self) -> bool:
        """True when a message written now goes straight out: the connection is open, nothing closes it,
        and the transport is not above its high-water mark (then the ASGI path waits; so does this one,
        by declining)."""
        p = self._protocol
        return not p.close_sent and not p.transport.is_closing() and p.writable.is_set()

    def write(self, frame: bytes) -> None:
        self._protocol.transport.write(frame)


def raw_socket(scope) -> RawSocket | None:
    """The connection of an accepted WebSocket, if it can be written directly; else None."""
    send = scope.get(SCOPE_KEY)
    protocol = getattr(send, "__self__", None)
    if type(protocol).__name__ != "WebSocketsSansIOProtocol":
        return None
    conn = getattr(protocol, "conn", None)
    if conn is None or getattr(conn, "extensions", None) != [] or not all(
            hasattr(protocol, a) for a in ("transport", "writable", "close_sent")):
        return None
    return RawSocket(protocol)


class Framing:
    """The WebSocket frame of the newest message of each kind (binary: a transform block, text: the state),
    built once for all pages."""

    def __init__(self):
        self._last: dict[Opcode, tuple[bytes, bytes]] = {}

    def __call__(self, data: bytes, opcode: Opcode = Opcode.BINARY) -> bytes:
        last = self._last.get(opcode)
        if last is None or last[0] is not data:
            last = self._last[opcode] = (data, Frame(opcode, data).serialize(mask=False))
        return last[1]
