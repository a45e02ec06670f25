"""A client's message is answered as its own mistake only when it is one (ProtocolError, KinetreError); any
other exception is the server's fault: logged with its traceback, told to the client as such, and the
connection goes on."""
import asyncio
import json
import logging

import pytest

from kinetre.errors import AttachError
from kinetre.studio.channels import Hub
from kinetre.studio.protocol import ProtocolError, parse_place
from kinetre.studio.subjects import client_subject
from kinetre.studio.viewer import Viewer


class Host:
    """A scene host whose commands raise `error` (the ones that reach it)."""

    def __init__(self, error: Exception | None):
        self.error = error
        self.commands: list[str] = []

    async def command(self, client: str, msg: dict, raw: bytes) -> None:
        self.commands.append(msg["type"])
        if self.error is not None:
            raise self.error


def answers(error: Exception | None, messages: list[str]) -> tuple[list[dict], Viewer, Host]:
    """What the client is told for each of `messages` sent in turn on one connection."""
    async def go():
        hub, host = Hub(), Host(error)
        viewer = Viewer(None, "c1", hub, host, None)
        replies = hub.subscribe(client_subject("c1"))
        for text in messages:
            await viewer.receive(text)
        out = []
        while (frame := replies.poll()) is not None:
            out.append(json.loads(frame.data))
        return out, viewer, host
    return asyncio.run(go())


def test_the_clients_mistakes_are_answered_as_such():
    told, viewer, host = answers(AttachError("nothing is near the mesh"),
                                 ['{"type": "possess"}', '{"type": "dance"}', 'not json', '{"type": "stats"}'])
    assert [t["type"] for t in told] == ["error", "error", "error", "stats"]  # the connection went on
    assert told[0]["message"] == "nothing is near the mesh"
    assert told[1]["message"] == "bad message: unknown message type 'dance'"
    assert told[2]["message"].startswith("bad message: not JSON")
    assert viewer.stats.malformed == 2 and host.commands == ["possess"]
    assert told[3]["malformed"] == 2


@pytest.mark.parametrize("bug", [TypeError("unsupported operand"), ValueError("math domain error"),
                                 KeyError("mesh"), RuntimeError("lost")])
def test_a_server_fault_is_logged_and_the_connection_survives(bug, caplog):
    with caplog.at_level(logging.ERROR, logger="kinetre.studio"):
        told, viewer, host = answers(bug, ['{"type": "fit"}', '{"type": "release"}'])
    assert [t["type"] for t in told] == ["error", "error"]
    assert all(t["message"].startswith(f"the server failed on this message ({type(bug).__name__})") for t in told)
    assert viewer.stats.malformed == 0  # not counted as the client's bad message
    assert host.commands == ["fit", "release"]
    faults = [r for r in caplog.records if r.exc_info and r.exc_info[1] is bug]
    assert len(faults) == 2


@pytest.mark.parametrize("msg, reason", [({"scale": "big"}, "scale must be a number"),
                                         ({"yaw": None}, "yaw must be a number"),
                                         ({"position": [0, "up", 0]}, "position must be a list of 3 numbers"),
                                         ({"position": [0, 0]}, "position must be a list of 3 numbers"),
                                         ({"position": {"x": 1}}, "position must be a list of 3 numbers")])
def test_a_bad_place_is_the_clients_mistake(msg, reason):
    with pytest.raises(ProtocolError, match=reason):
        parse_place({"type": "place", **msg})


def test_a_place_reads_its_numbers_with_defaults():
    assert parse_place({"type": "place"}) == (1.0, [0, 0, 0], 0.0)
    assert parse_place({"type": "place", "scale": 2, "position": [1, 0.5, -2], "yaw": 0.25}) == \
        (2.0, [1, 0.5, -2], 0.25)
