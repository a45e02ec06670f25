"""The NATS bus's own hot path over a real nats-server: frames published in the caller's call (also when
nats-py has to wait for its flusher), live subscriptions delivered in the connection's reader, and the
scene parsing only the frames it needs (users who do not possess are parsed when they fit or possess)."""
import asyncio
import json
import time
from types import SimpleNamespace

import numpy as np
import pytest
from studio.nats_server import ROOMS, NatsServer
from studio.studio_ws import frame_message

from kinetre.studio import natsbus
from kinetre.studio.channels import Frame, Hub
from kinetre.studio.meshes import data_path, prepare_mesh
from kinetre.studio.natsbus import NatsChannels
from kinetre.studio.natspatch import DirectDelivery, ReadNow, Resumed
from kinetre.studio.protocol import SkeletonFrame
from kinetre.studio.remote import SceneMirror
from kinetre.studio.scene import Scene
from kinetre.studio.subjects import STATE


@pytest.fixture(scope="module")
def nats():
    with NatsServer() as server:
        yield server


async def pair(url):
    sender = await NatsChannels.connect(url, "a", ROOMS["a"], name="sender")
    receiver = await NatsChannels.connect(url, "a", ROOMS["a"], name="receiver")
    return sender, receiver


async def collect(sub, count, timeout=10.0):
    got = []
    while len(got) < count:
        frame = await sub.next(timeout)
        if frame is None:
            break
        got.append(frame)
    return got


def test_frames_reach_the_wire_in_the_publishers_call(nats):
    """No task of ours between publish and the connection: nats-py's pending buffer holds the frame when
    publish returns, and the receiver's subscription gets every frame, in order, from the reader."""
    async def go():
        sender, receiver = await pair(nats.url)
        sub = receiver.subscribe("kinetre.command.x")  # queued subject: every frame is kept
        await receiver.ready()
        assert isinstance(receiver._subs["kinetre.a.command.x"]._pending_queue, DirectDelivery)
        before = sender.nc.stats["out_msgs"]
        for seq in range(1, 51):
            sender.publish(Frame("kinetre.command.x", seq, float(seq), b"frame %d" % seq))
        assert sender.nc.stats["out_msgs"] - before == 50 and sender.counters.published == 50
        assert sender.counters.written == 50  # nothing else pending: every PUB went to the socket at once
        got = await collect(sub, 50)
        read_now = receiver.nc._transport._io_reader.feed_data
        await sender.close()
        await receiver.close()
        return got, read_now
    got, read_now = asyncio.run(go())
    assert isinstance(read_now, ReadNow) and read_now.parsed > 0  # parsed in the socket's callback
    assert [f.seq for f in got] == list(range(1, 51))
    assert [f.data for f in got] == [b"frame %d" % s for s in range(1, 51)]


def test_frames_written_at_once_keep_their_order_behind_nats_pys_buffer(nats):
    """A frame is written to the socket in the publisher's call only when nats-py's pending buffer is empty:
    behind a message nats-py still holds (a request, a reply, a command published through it) it waits its
    turn in that buffer, so the receiver gets every frame in publishing order."""
    async def go():
        sender, receiver = await pair(nats.url)
        sub = receiver.subscribe("kinetre.command.z")
        await receiver.ready()
        for seq in range(1, 61):
            frame = Frame("kinetre.command.z", seq, float(seq), b"%d" % seq)
            if seq % 4 == 0:  # through nats-py: into its pending buffer, written later by its flusher task
                await sender.nc.publish("kinetre.a.command.z", natsbus.pack(frame))
            else:
                sender.publish(frame)
            if seq % 12 == 0:
                await asyncio.sleep(0)  # the flusher runs: the buffer is empty again
        got = await collect(sub, 60)
        await sender.close()
        await receiver.close()
        return got, sender.counters
    got, counters = asyncio.run(go())
    assert [f.seq for f in got] == list(range(1, 61))
    assert counters.published == 45 and 0 < counters.written < 45  # some waited behind nats-py's buffer


def test_batched_subjects_wait_for_nats_pys_flusher_and_keep_the_order(nats):
    """Frames on a `batched` subject are never written in the publisher's call (nats-py's flusher writes
    everything pending in one go); a frame on another subject behind them waits its turn."""
    async def go():
        sender, receiver = await pair(nats.url)
        sub = receiver.subscribe("kinetre.command.*")
        await receiver.ready()
        sender.batched = frozenset({"kinetre.command.other"})
        for seq in range(1, 21):
            subject = "kinetre.command.other" if seq % 2 else "kinetre.command.mine"
            sender.publish(Frame(subject, seq, float(seq), b"%d" % seq))
        written_in_burst = sender.counters.written
        await asyncio.sleep(0.05)  # the flusher has written the burst
        sender.publish(Frame("kinetre.command.mine", 21, 21.0, b"21"))
        got = await collect(sub, 21)
        await sender.close()
        await receiver.close()
        return written_in_burst, got, sender.counters
    written_in_burst, got, counters = asyncio.run(go())
    assert written_in_burst == 0  # the first frame was batched: every later one waited behind it
    assert counters.written == 1 and counters.published == 21
    assert [f.seq for f in got] == list(range(1, 22))


def test_gateway_batches_the_frames_of_users_who_do_not_possess():
    """The gateway's mirror of the scene's state names the users nobody waits for: their skeleton frames
    are batched, the possessing users' frames are written at once."""
    async def go():
        bus = NatsChannels("a")  # not connected: local delivery only
        mirror = SceneMirror(bus)
        task = asyncio.get_running_loop().create_task(mirror.run())
        await asyncio.sleep(0)
        users = [{"client": "s1-c1", "possessing": True}, {"client": "s1-c2", "possessing": False},
                 {"client": "s2-c1", "possessing": False}]
        bus.deliver_local(Frame(STATE, 1, 0.0, json.dumps({"type": "state", "users": users}).encode()))
        await asyncio.sleep(0.01)
        first = bus.batched
        users[1]["possessing"] = True
        bus.deliver_local(Frame(STATE, 2, 0.0, json.dumps({"type": "state", "users": users}).encode()))
        await asyncio.sleep(0.01)
        task.cancel()
        return first, bus.batched
    first, then = asyncio.run(go())
    assert first == {"kinetre.skeleton.s1-c2", "kinetre.skeleton.s2-c1"}
    assert then == {"kinetre.skeleton.s2-c1"}


def test_a_publish_that_must_wait_for_the_flusher_still_arrives_in_order(nats, monkeypatch):
    """With nats-py's pending buffer over its limit every publish waits for the flusher: the rest of the
    call goes on in a task, and nothing is lost or reordered."""
    async def go():
        sender, receiver = await pair(nats.url)
        sub = receiver.subscribe("kinetre.command.y")
        await receiver.ready()
        # through nats-py's buffer, as when it holds data
        monkeypatch.setattr(natsbus, "write_pub", lambda nc, subject, payload: False)
        sender.nc._max_pending_size = 1  # every PUB is over the limit: nats-py forces a flush and waits
        for seq in range(1, 31):
            sender.publish(Frame("kinetre.command.y", seq, float(seq), bytes(1000)))
        waited = len(sender._finishing)
        got = await collect(sub, 30)
        await asyncio.sleep(0.1)
        left = len(sender._finishing)
        await sender.close()
        await receiver.close()
        return waited, left, got, sender.counters
    waited, left, got, counters = asyncio.run(go())
    assert waited > 0 and left == 0  # it did have to wait, and every waiting publish finished
    assert [f.seq for f in got] == list(range(1, 31)) and counters.published == 30 and counters.offline == 0


def test_reads_are_parsed_in_the_sockets_callback_in_order():
    """While nats-py's reader waits for data, each read is parsed at once; a parse that must wait finishes
    in a task and the reads behind it are parsed after it, in order; while nats-py's reader is not waiting
    (it has data of its own to parse), reads go to it as before."""
    class Parser:
        def __init__(self):
            self.got, self.gate = [], None

        async def parse(self, data):
            if data == b"slow":
                self.gate = asyncio.get_running_loop().create_future()
                await self.gate
            self.got.append(data)

    async def go():
        reader = asyncio.StreamReader()
        nc = SimpleNamespace(_ps=Parser(), _transport=SimpleNamespace(_io_reader=reader))
        assert ReadNow.install(nc)
        reading = asyncio.get_running_loop().create_task(reader.read(100))  # nats-py's reader, waiting
        await asyncio.sleep(0)
        for data in (b"a", b"slow", b"b", b"c"):
            reader.feed_data(data)
        during = list(nc._ps.got)
        nc._ps.gate.set_result(None)
        for _ in range(5):
            await asyncio.sleep(0)
        after = list(nc._ps.got)
        idle_reader_got_nothing = not reading.done()
        reading.cancel()
        await asyncio.sleep(0)
        reader.feed_data(b"d")  # nobody waits in read(): nats-py's own buffer keeps it for its reader
        return during, after, idle_reader_got_nothing, bytes(reader._buffer), nc._ps.got
    during, after, idle, buffered, got = asyncio.run(go())
    assert during == [b"a"] and after == [b"a", b"slow", b"b", b"c"] and idle
    assert buffered == b"d" and got == after


def test_resumed_coroutine_ends_as_the_coroutine_would():
    async def later(x):
        await asyncio.sleep(0.01)
        return 2 * x

    async def failing():
        await asyncio.sleep(0.01)
        raise ValueError("nope")

    async def go():
        call = later(21)
        waiting = call.send(None)  # runs up to the sleep
        value = await Resumed(call, waiting)
        call = failing()
        waiting = call.send(None)
        with pytest.raises(ValueError, match="nope"):
            await Resumed(call, waiting)
        return value
    assert asyncio.run(go()) == 42


def test_live_subjects_are_latest_wins_over_the_direct_subscription(nats):
    """A slow reader of a live subject gets the newest frame only; late frames are dropped and counted."""
    async def go():
        sender, receiver = await pair(nats.url)
        sub = receiver.subscribe("kinetre.skeleton.*")
        await receiver.ready()
        for seq in (1, 2, 3, 2):
            sender.publish(Frame("kinetre.skeleton.u", seq, float(seq), b"{}"))
        await sender.nc.flush()
        await asyncio.sleep(0.2)
        first = await sub.next(1.0)
        again = await sub.next(0.2)
        await sender.close()
        await receiver.close()
        return first, again, receiver.counters
    first, again, counters = asyncio.run(go())
    assert first.seq == 3 and again is None
    assert counters.received == 4 and counters.late == 1 and counters.gaps == 0


def test_scene_parses_a_users_frames_only_when_needed(walk):
    """Frames off the bus (no decoded value) of a user who does not possess are kept as bytes; fit and
    possess parse the newest; a frame that does not parse leaves the last good one; a possessing user's
    frames are parsed on arrival."""
    mesh, graph = prepare_mesh(str(data_path("spot.obj")), 32)

    async def go():
        # raw frames (`kinetre studio --raw`): a cleaned user's frames are all parsed, for the filter sees each
        scene = Scene(Hub(), mesh, graph, "spot.obj", clean=False)

        def send(seq, skeleton=None, data=None):
            data = data if data is not None else frame_message(seq, skeleton, t=float(seq)).encode()
            scene.receive(Frame("kinetre.skeleton.u", seq, float(seq), data))
        send(1, walk[0])
        user = scene.users["u"]
        assert user.raw is not None and user.parsed is None and user.frames == 1
        send(2, walk[5])
        np.testing.assert_allclose(user.latest.positions, walk[5].positions, atol=1e-9)
        assert user.raw is None
        send(3, data=b'{"type": "skeleton", "seq": 3}')  # not a skeleton: the last good frame stays
        assert user.frames == 3 and user.seq == 3
        np.testing.assert_allclose(user.latest.positions, walk[5].positions, atol=1e-9)
        send(2, walk[9])  # late: dropped before anything is kept
        assert scene.users.late == 1 and user.raw is None
        send(4, walk[10])
        scene.fit("u")
        await scene.possess("u")
        np.testing.assert_allclose(user.latest.positions, walk[10].positions, atol=1e-9)
        send(5, walk[12])  # possessing: parsed now, it drives the next solve
        assert user.raw is None
        np.testing.assert_allclose(user.latest.positions, walk[12].positions, atol=1e-9)
        send(6, data=b"not json")  # a possessing user's bad frame is dropped, not counted
        assert user.seq == 5 and user.frames == 5
        pose = await scene.solve_once()
        return pose
    assert asyncio.run(go()) is not None


class SlowSolver:
    """A stand-in for the solve worker: each solve takes `seconds` and records the frames it was given."""

    def __init__(self, graph, seconds=0.02):
        self.graph, self.seconds, self.cpu_ms, self.solved = graph, seconds, 0.0, []

    async def attach(self, graph, skeletons, settings=None):
        return [np.arange(3)] * (len(skeletons) if isinstance(skeletons, list) else 1)

    def newer_frame(self):
        pass

    async def solve(self, skeletons, overdue=False):
        from kinetre.deform.pose import GraphPose
        self.solved.append([round(float(s.positions[0, 0]), 3) for s in skeletons])
        await asyncio.sleep(self.seconds)
        return GraphPose.identity(self.graph.node_count)

    def submit(self, skeletons, overdue, ended):
        from kinetre.studio.scene.solve_worker import submitted
        submitted(self.solve(skeletons, overdue), ended)


def run_two_users(walk, monkeypatch, offset_s, stamped_in_step=False, solve_s=0.02):
    """Two possessing users at 30 Hz, the second's frames `offset_s` after the first's on the scene's clock
    (faked, so the periods it learns are exact). Returns the frames each solve took after a second of that
    (joint 0's x tells the frames apart), the newest frames' x, and what the scene does when only the
    first user's frames go on. `stamped_in_step`: both senders stamp a tick's frames with the tick's time
    (else each frame's stamp is its sequence number, which tells nothing of ticks); a solve takes `solve_s`."""
    from kinetre.studio.scene import solve_loop, users
    mesh, graph = prepare_mesh(str(data_path("spot.obj")), 32)
    clock = [1000.0]
    for module in (users, solve_loop):  # frame arrivals and the solve loop's deadlines
        monkeypatch.setattr(module, "time", SimpleNamespace(monotonic=lambda: clock[0],
                                                            perf_counter=time.perf_counter, time=time.time))

    async def go():
        solver = SlowSolver(graph, solve_s)
        # raw frames: the solver must be handed each frame's own positions, which cleaning would smooth
        scene = Scene(Hub(), mesh, graph, "spot.obj", solver=solver, clean=False)
        seq = [0]

        def send(user, skeleton, k=None):
            seq[0] += 1
            t = 1000.0 * k / 30 + 0.2 * (user == "b") if stamped_in_step and k is not None else float(seq[0])
            scene.receive(Frame(f"kinetre.skeleton.{user}", seq[0], t, b"", SkeletonFrame(seq[0], t, skeleton)))
        for user in ("a", "b"):
            send(user, walk[0])
            await scene.possess(user)

        def tick(k):
            clock[0] = 1000.0 + k / 30
            send("a", walk[k], k)
            clock[0] += offset_s
            send("b", walk[k], k)
        for k in range(1, 31):
            tick(k)
        task = asyncio.get_running_loop().create_task(scene.run())
        await asyncio.sleep(0.1)  # one solve of the newest frames
        solver.solved.clear()
        clock[0] = 1000.0 + 31 / 30  # the next tick
        send("a", walk[40], 31)
        for _ in range(3):
            await asyncio.sleep(0)  # the scene sees it and decides whether to wait
        clock[0] += offset_s
        send("b", walk[40], 31)
        await asyncio.sleep(0.1)
        solved = list(solver.solved)  # the solves of walk[40]; each mesh's solve loop may take walk[41] next
        clock[0] += 0.5  # the second user stopped: the first's next frame is not held for it
        send("a", walk[41], 46)
        later = scene.solves.gather_deadline(scene.meshes.first, clock[0])
        task.cancel()
        return solved, round(float(walk[40].positions[0, 0]), 3), later
    return asyncio.run(go())


def test_a_solve_waits_for_a_possessors_frame_that_is_due(walk, monkeypatch):
    """Frames of two possessors in step are solved together, once; a user whose frame is not due within half
    a solve (out of step, or stopped sending) is not waited for: its frame gets a solve of its own."""
    solved, x, later = run_two_users(walk, monkeypatch, 0.003)
    assert solved == [[x, x]] and later is None
    solved, x, _ = run_two_users(walk, monkeypatch, 0.016)  # half a period out of step; a solve takes 20 ms
    assert solved[0][0] == x and solved[0][1] != x and solved[1] == [x, x]


def test_frames_their_senders_stamp_in_one_tick_are_solved_together_however_late_the_second_arrives(
        walk, monkeypatch):
    """Two people in one camera (or cameras ticking together): their frames carry the same tick's time, so the
    second is waited for even when it arrives later than half a solve after the first (9 ms; a solve takes
    10); frames stamped otherwise are not; and not once the second sender has stopped."""
    solved, x, later = run_two_users(walk, monkeypatch, 0.009, stamped_in_step=True, solve_s=0.01)
    assert solved == [[x, x]] and later is None
    solved, x, _ = run_two_users(walk, monkeypatch, 0.009, stamped_in_step=False, solve_s=0.01)
    assert solved[0][0] == x and solved[0][1] != x


def test_a_nats_py_the_fast_paths_were_not_checked_against_is_refused_before_connecting(monkeypatch):
    """natspatch relies on nats-py internals: the installed version is one it names, and any other stops
    `start` with a line saying what to install (no connection is tried: the URL has no server)."""
    import importlib.metadata

    from kinetre.studio.natspatch import CHECKED_VERSIONS, NatsVersionError, check_nats_version
    assert check_nats_version() in CHECKED_VERSIONS
    monkeypatch.setattr(importlib.metadata, "version", lambda name: "2.9.0")
    with pytest.raises(NatsVersionError) as refused:
        asyncio.run(NatsChannels("a").start("nats://127.0.0.1:9"))
    assert str(refused.value).startswith("nats-py 2.9.0 is installed")
    assert f"pip install nats-py=={CHECKED_VERSIONS[-1]}" in str(refused.value)
