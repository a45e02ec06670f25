"""Who may use a studio: its room's token, checked on every HTTP request and WebSocket.

The link to share is `http://HOST:PORT/?token=TOKEN`: the page's first request carries the token and
gets it back as a cookie for the room, so its later fetches and its WebSocket need nothing more.
Scripts may send `Authorization: Bearer TOKEN` or `?token=` on any request instead. A studio without
a token answers only on the loopback interface (`check_bind`).
"""
from __future__ import annotations

import hmac
import ipaddress
import json
from http.cookies import SimpleCookie
from urllib.parse import parse_qs

from ..errors import KinetreError

WS_REFUSED = 4401  # WebSocket close code: wrong or missing token


class AccessError(KinetreError):
    """The studio would be reachable from the network without a token."""


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_bind(host: str, token: str | None) -> None:
    if not token and not is_loopback(host):
        raise AccessError(f"--host {host} would let anyone on the network drive the studio: "
                          "give the room a token (--token SECRET) or keep --host 127.0.0.1")


def cookie_name(room: str) -> str:
    return f"kinetre_{room}"


class TokenGate:
    """ASGI middleware: refuses requests without the room's token (401 JSON / WebSocket close 4401)."""

    def __init__(self, app, room: str, token: str | None):
        self.app, self.room, self.token = app, room, token

    def presented(self, scope) -> tuple[str | None, bool]:
        """(token presented, whether it came in the query string)."""
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        if "token" in query:
            return query["token"][-1], True
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        auth = headers.get("authorization", "")
        if auth.lower().startswith("bearer "):
            return auth[7:].strip(), False
        cookie = SimpleCookie()
        try:
            cookie.load(headers.get("cookie", ""))
        except Exception:
            return None, False
        morsel = cookie.get(cookie_name(self.room))
        return (morsel.value if morsel else None), False

    def allowed(self, given: str | None) -> bool:
        return given is not None and hmac.compare_digest(given.encode(), self.token.encode())

    async def __call__(self, scope, receive, send):
        if self.token is None or scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        given, in_query = self.presented(scope)
        if self.allowed(given):
            if scope["type"] == "http" and in_query:
                send = self._setting_cookie(send)
            return await self.app(scope, receive, send)
        reason = (f"room '{self.room}' needs its token: open the link you were given (…/?token=…)"
                  if given is None else f"room '{self.room}': wrong token")
        if scope["type"] == "websocket":
            await receive()  # websocket.connect
            await send({"type": "websocket.accept"})  # accept, so the page can show why
            await send({"type": "websocket.send", "text": json.dumps({"type": "error", "message": reason})})
            await send({"type": "websocket.close", "code": WS_REFUSED, "reason": reason[:120]})
            return
        body = json.dumps({"error": reason}).encode()
        await send({"type": "http.response.start", "status": 401,
                    "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]})
        await send({"type": "http.response.body", "body": body})

    def _setting_cookie(self, send):
        value = f"{cookie_name(self.room)}={self.token}; Path=/; HttpOnly; SameSite=Strict".encode()

        async def wrapped(message):
            if message["type"] == "http.response.start":
                message = dict(message, headers=list(message.get("headers", [])) + [(b"set-cookie", value)])
            await send(message)
        return wrapped
