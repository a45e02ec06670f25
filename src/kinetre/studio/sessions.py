"""A page's identity outlives a dropped connection: who it is, and so what it possesses, survives a reconnect.

Every WebSocket gets a client name and a secret resume token (in its welcome). A connection that ends cleanly
(the page closed it, or navigated away) forgets its user at once. One that drops (a network blip, a missed
keep-alive ping on a busy machine) keeps its user, possessions included, for `RESUME_S`: the page reconnects
with `?resume=CLIENT.TOKEN` and goes on as the same user, bound as it was, instead of a stranger whose people
have let go of their meshes while the page still shows them possessing.
"""
from __future__ import annotations

import asyncio
import hmac
import itertools
import secrets
from dataclasses import dataclass, field
from typing import Callable

RESUME_S = 15.0  # how long a dropped page's user waits for it to come back
# closed on purpose, or the page going away; not 1005 ("no status"), which the server reports for a dropped
# connection as well as for a close frame without a code
CLEAN_CLOSE = frozenset({1000, 1001})


@dataclass
class _Held:
    token: str
    connections: int = 0  # open connections as this client (two, briefly, while one takes over another)
    expiry: asyncio.TimerHandle | None = None


@dataclass
class Sessions:
    """The studio's client names and their resume tokens. `forget(client)` is called once a client is gone
    for good."""
    forget: Callable[[str], None]
    prefix: str = ""  # client names unique across studios of a room
    grace_s: float = RESUME_S
    _names: itertools.count = field(default_factory=lambda: itertools.count(1))
    _held: dict[str, _Held] = field(default_factory=dict)

    def open(self, resume: str | None) -> tuple[str, str]:
        """(client, token) for a new connection: the client named by a valid `resume` ("CLIENT.TOKEN") if its
        user is still held, else a new client."""
        client, _, token = (resume or "").rpartition(".")
        held = self._held.get(client)
        if held is None or not hmac.compare_digest(held.token, token):
            client = f"{self.prefix}c{next(self._names)}"
            held = self._held[client] = _Held(secrets.token_urlsafe(16))
        if held.expiry is not None:
            held.expiry.cancel()
            held.expiry = None
        held.connections += 1
        return client, held.token

    def close(self, client: str, code: int | None) -> None:
        """A connection of `client` ended with WebSocket close `code`: forgotten now if it closed on purpose
        and no other connection took it over; kept for `grace_s` if it dropped."""
        held = self._held.get(client)
        if held is None:
            return
        held.connections -= 1
        if held.connections > 0:
            return
        if code in CLEAN_CLOSE or self.grace_s <= 0:
            self._drop(client)
        else:
            held.expiry = asyncio.get_running_loop().call_later(self.grace_s, self._drop, client)

    def held(self, client: str) -> bool:
        """Whether `client` is connected, or dropped and still waited for."""
        return client in self._held

    def _drop(self, client: str) -> None:
        if self._held.pop(client, None) is not None:
            self.forget(client)
