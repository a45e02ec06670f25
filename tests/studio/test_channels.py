"""The embedded hub: NATS subject matching and latest-wins delivery (avateering paper §2)."""
import asyncio

import pytest

from kinetre.studio.channels import Frame, Hub, subject_matches


@pytest.mark.parametrize("pattern, subject, expected", [
    ("kinetre.skeleton.*", "kinetre.skeleton.c1", True),
    ("kinetre.skeleton.*", "kinetre.skeleton", False),
    ("kinetre.skeleton.*", "kinetre.skeleton.c1.x", False),
    ("kinetre.>", "kinetre.skeleton.c1", True),
    ("kinetre.>", "kinetre", False),
    ("kinetre.transforms", "kinetre.transforms", True),
    ("kinetre.transforms", "kinetre.state", False),
])
def test_subject_matching_follows_nats(pattern, subject, expected):
    assert subject_matches(pattern, subject) is expected


def test_slow_subscriber_gets_only_the_newest_frame_per_subject():
    async def run():
        hub = Hub()
        sub = hub.subscribe("kinetre.skeleton.*")
        for seq in range(1, 1001):
            hub.publish(Frame("kinetre.skeleton.a", seq, float(seq), b"a"))
            if seq % 10 == 0:
                hub.publish(Frame("kinetre.skeleton.b", seq, float(seq), b"b"))
        got = [await sub.next(timeout=1) for _ in range(2)]
        rest = await sub.next(timeout=0.05)
        return got, rest, sub.skipped

    got, rest, skipped = asyncio.run(run())
    assert [(f.subject, f.seq) for f in got] == [("kinetre.skeleton.a", 1000), ("kinetre.skeleton.b", 1000)]
    assert rest is None  # nothing queued behind the newest frames
    assert skipped == 999 + 99


def test_subscribers_are_independent_and_closed_ones_stop_receiving():
    async def run():
        hub = Hub()
        fast, slow = hub.subscribe("t"), hub.subscribe("t", "u")
        seen = []
        for seq in range(5):
            hub.publish(Frame("t", seq, 0.0, b""))
            seen.append((await fast.next(timeout=1)).seq)
        hub.publish(Frame("u", 7, 0.0, b""))
        slow_frames = [(await slow.next(timeout=1)).seq, (await slow.next(timeout=1)).seq]
        fast.close()
        hub.publish(Frame("t", 9, 0.0, b""))
        return seen, slow_frames, await fast.next(timeout=0.05), len(hub._subs)

    seen, slow_frames, after_close, subs = asyncio.run(run())
    assert seen == [0, 1, 2, 3, 4]
    assert slow_frames == [4, 7]
    assert after_close is None and subs == 1


def test_next_times_out_without_frames_and_a_frame_ends_the_wait():
    """With nothing published, `next` gives None once its timeout passes; a frame published meanwhile is
    returned instead (a generous timeout: the frame, not the clock, ends that wait)."""
    async def run():
        hub = Hub()
        sub = hub.subscribe("x")
        nothing = await sub.next(timeout=0.05)
        asyncio.get_running_loop().call_soon(hub.publish, Frame("x", 1, 0.0, b"f"))
        frame = await sub.next(timeout=60)
        return nothing, frame

    nothing, frame = asyncio.run(run())
    assert nothing is None
    assert frame is not None and frame.seq == 1 and frame.data == b"f"


def test_urgent_subjects_jump_the_line():
    async def run():
        hub = Hub()
        sub = hub.subscribe("kinetre.skeleton.*", urgent=("kinetre.transforms",))
        for i in range(5):
            hub.publish(Frame(f"kinetre.skeleton.c{i}", 1, 0.0, b""))
        hub.publish(Frame("kinetre.transforms", 9, 0.0, b""))
        return [(await sub.next(timeout=1)).subject for _ in range(6)]

    order = asyncio.run(run())
    assert order[0] == "kinetre.transforms"
    assert order[1:] == [f"kinetre.skeleton.c{i}" for i in range(5)]


def test_replies_are_queued_while_live_data_is_latest_wins():
    """Every error message reaches its page (under load they were once merged); frames still merge."""
    async def run():
        hub = Hub()
        sub = hub.subscribe("kinetre.skeleton.*", urgent=("kinetre.client.c1",))
        for i in range(3):
            hub.publish(Frame("kinetre.skeleton.c2", i, 0.0, b""))
            hub.publish(Frame("kinetre.client.c1", 0, 0.0, f"error {i}".encode()))
        got = []
        while (frame := sub.poll()) is not None:
            got.append((frame.subject, frame.seq, frame.data))
        return got, sub.skipped

    got, skipped = asyncio.run(run())
    assert got == [("kinetre.client.c1", 0, b"error 0"), ("kinetre.client.c1", 0, b"error 1"),
                   ("kinetre.client.c1", 0, b"error 2"), ("kinetre.skeleton.c2", 2, b"")]
    assert skipped == 2
