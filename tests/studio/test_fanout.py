"""Transform blocks written straight to a page's socket (fanout.py), over a real uvicorn server: the page
receives exactly the bytes, in order with what goes through ASGI; with permessage-deflate negotiated (or
another server) the direct path declines and ASGI carries everything."""
import asyncio
import os

import pytest
import uvicorn
from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.routing import WebSocketRoute
from websockets.asyncio.client import connect

from kinetre.studio.fanout import Framing, RawSockets, raw_socket

from studio.conftest import free_port


async def serve_and_receive(deflate: bool, count: int = 3) -> tuple[list, bool]:
    blocks = [os.urandom(n) for n in (12176, 125, 70000)][:count]  # 7-bit, 16-bit and 64-bit lengths
    used = {}

    async def endpoint(ws):
        await ws.accept()
        raw = raw_socket(ws.scope)
        used["raw"] = raw is not None
        framing = Framing()
        await ws.send_text("first")
        for block in blocks:
            if raw is not None and raw.ready():
                raw.write(framing(block))
                assert framing(block) is framing(block)  # framed once per block
            else:
                await ws.send_bytes(block)
        await ws.send_text("last")
        await ws.receive()  # until the client goes

    app = Starlette(routes=[WebSocketRoute("/ws", endpoint)], middleware=[Middleware(RawSockets)])
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning",
                                           ws_per_message_deflate=deflate))
    task = asyncio.get_running_loop().create_task(server.serve())
    try:
        while not server.started:
            await asyncio.sleep(0.02)
        got = []
        async with connect(f"ws://127.0.0.1:{port}/ws", max_size=1 << 20) as ws:
            for _ in range(len(blocks) + 2):
                got.append(await asyncio.wait_for(ws.recv(), 30))
        return ["first", *blocks, "last"] == got, used["raw"]
    finally:
        server.should_exit = True
        await task


@pytest.mark.parametrize("deflate", [False, True])
def test_blocks_written_directly_arrive_intact_and_in_order(deflate):
    same, direct = asyncio.run(serve_and_receive(deflate))
    assert same
    assert direct == (not deflate)  # a negotiated extension would need its own framing: ASGI then


def test_no_server_connection_means_no_direct_path():
    assert raw_socket({"type": "websocket"}) is None
    assert raw_socket({"type": "websocket", "kinetre.send": lambda message: None}) is None
