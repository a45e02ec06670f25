"""A page whose connection drops comes back as the same user, still possessing its mesh; one that closes on
purpose is forgotten at once; a resume token is needed to take a user's place."""
from __future__ import annotations

import asyncio

import pytest

from kinetre.studio.sessions import Sessions
from studio.studio_ws import StudioClient, possessed_client


def test_a_dropped_client_is_held_for_its_grace_and_then_forgotten():
    async def go():
        gone: list[str] = []
        sessions = Sessions(gone.append, grace_s=0.2)
        client, token = sessions.open(None)
        # dropped: no closing handshake (the server reports it as a close frame without a code would be)
        sessions.close(client, 1005)
        assert sessions.held(client) and gone == []
        again, same = sessions.open(f"{client}.{token}")
        assert (again, same) == (client, token)
        sessions.close(again, 1011)  # a keep-alive ping unanswered
        await asyncio.sleep(0.4)
        assert gone == [client] and not sessions.held(client)
        late, _ = sessions.open(f"{client}.{token}")  # too late: a new user
        assert late != client

    asyncio.run(go())


def test_a_clean_close_forgets_at_once_and_a_wrong_token_is_a_stranger():
    gone: list[str] = []
    sessions = Sessions(gone.append, grace_s=60)
    client, token = sessions.open(None)
    other, _ = sessions.open(f"{client}.{token[::-1]}")
    assert other != client
    sessions.close(client, 1000)
    assert gone == [client]
    # a page that reconnected before the server noticed its old connection drop: the old one's end is no loss
    third, token3 = sessions.open(None)
    assert sessions.open(f"{third}.{token3}")[0] == third
    sessions.close(third, 1006)
    assert gone == [client] and sessions.held(third)
    sessions.close(third, 1000)
    assert gone == [client, third]


@pytest.mark.slow
def test_a_page_that_drops_comes_back_possessing_and_one_that_leaves_is_gone(studio, walk):
    async def go():
        async with StudioClient(studio) as watcher:
            page = await possessed_client(studio, walk)
            client, resume = page.client, page.resume
            await page.drop()
            back = StudioClient(studio, resume=resume)
            await back.__aenter__()
            assert back.client == client
            assert back.me()["possessing"] and back.me()["mesh"] is not None
            seen = watcher.transform_count
            await back.perform(walk, 100, lambda c: c.transform_count >= seen + 3, watcher)
            await back.__aexit__(None, None, None)  # leaves on purpose: forgotten, not held
            await watcher.wait(lambda c: all(u["client"] != client for u in c.state["users"]), 30)
            stranger = StudioClient(studio, resume=resume)
            await stranger.__aenter__()
            assert stranger.client != client
            await stranger.__aexit__(None, None, None)

    asyncio.run(go())
