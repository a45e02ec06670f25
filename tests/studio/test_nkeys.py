"""Rooms authenticated by NATS nkeys instead of tokens, over a real nats-server: the room's seed gets in (a
`kinetre scene --nkey` too), a wrong seed or a file that holds none is refused with a message naming it, and
the server's permissions keep a room's nkey out of another room's subjects."""
import asyncio
import json
import os
import subprocess
import sys
import time

import pytest
from studio.nats_server import ROOMS, NatsServer

from kinetre.cli import main
from kinetre.studio.channels import Frame
from kinetre.studio.natsbus import NatsChannels, NetworkError, nkey_public, room_nkey, server_config


@pytest.fixture(scope="module")
def rooms(tmp_path_factory):
    """Room a by nkey, room b by token; plus a seed the server has never heard of."""
    folder = tmp_path_factory.mktemp("nkeys")
    seed_a, stranger = folder / "a.nk", folder / "stranger.nk"
    public_a = room_nkey(seed_a)
    room_nkey(stranger)
    with NatsServer({"a": public_a, "b": ROOMS["b"]}) as nats:
        yield {"nats": nats, "seed_a": seed_a, "public_a": public_a, "stranger": stranger, "folder": folder}


def test_room_nkey_files(rooms):
    seed = rooms["seed_a"]
    assert oct(os.stat(seed).st_mode & 0o777) == "0o600"  # the room's secret
    assert seed.read_text().startswith("SU") and nkey_public(seed) == rooms["public_a"]
    config = server_config({"a": rooms["public_a"], "b": "tok"}, 4222)
    assert f'nkey: "{rooms["public_a"]}"' in config and 'user: "b", password: "tok"' in config
    assert seed.read_text().strip() not in config  # only the public key goes to the server


def test_the_rooms_seed_gets_in_and_others_are_refused(rooms):
    url = rooms["nats"].url
    not_a_seed = rooms["folder"] / "notes.txt"
    not_a_seed.write_text("SUthis is not a seed\n")

    async def go():
        a = await NatsChannels.connect(url, "a", nkey=rooms["seed_a"])
        also_a = await NatsChannels.connect(url, "a", nkey=str(rooms["seed_a"]))
        sub = also_a.subscribe("kinetre.skeleton.*")
        await also_a.ready()
        a.publish(Frame("kinetre.skeleton.u1", 7, 123.0, b'{"type": "skeleton"}'))
        got = await sub.next(10)
        await a.close()
        await also_a.close()
        errors = {}
        for name, kwargs in {"stranger": {"nkey": rooms["stranger"]}, "not_a_seed": {"nkey": not_a_seed},
                             "missing": {"nkey": rooms["folder"] / "nope.nk"}, "no_credentials": {},
                             "room_b_token": {"token": ROOMS["b"]}}.items():
            with pytest.raises(NetworkError) as err:
                await NatsChannels.connect(url, "a", **kwargs)
            errors[name] = str(err.value)
        return got, errors

    got, errors = asyncio.run(go())
    assert got is not None and (got.subject, got.seq, got.t) == ("kinetre.skeleton.u1", 7, 123.0)
    assert f"the nkey in {rooms['stranger']} is not the room's" in errors["stranger"]
    assert str(not_a_seed) in errors["not_a_seed"] and "not an nkey seed" in errors["not_a_seed"]
    assert "nope.nk" in errors["missing"] and "cannot read" in errors["missing"]
    assert "refused" in errors["no_credentials"] and "refused" in errors["room_b_token"]
    # the command line: one line, exit 2
    assert main(["scene", "--nats", url, "--room", "a", "--nkey", str(rooms["stranger"])]) == 2
    assert main(["studio", "--nats", url, "--room", "a", "--nkey", str(not_a_seed), "--no-browser"]) == 2


def test_a_rooms_nkey_stays_in_its_room(rooms):
    """With room a's seed, room b's subjects can be neither read nor written (the server's permissions)."""
    url = rooms["nats"].url

    async def go():
        b = await NatsChannels.connect(url, "b", ROOMS["b"])
        seen_b = b.subscribe("kinetre.skeleton.*", "kinetre.transforms.*")
        await b.ready()
        spy = await NatsChannels.connect(url, "a", nkey=rooms["seed_a"])
        spy.prefix = "kinetre.b."  # room a's key, room b's subjects
        spied = spy.subscribe("kinetre.skeleton.*")
        with pytest.raises(NetworkError, match="ermissions violation"):
            await spy.ready()
        spy.publish(Frame("kinetre.skeleton.intruder", 1, 1.0, b"{}"))
        await asyncio.sleep(0.5)
        result = seen_b.poll(), spied.poll()
        await b.close()
        await spy.close()
        return result

    assert asyncio.run(go()) == (None, None)


def test_scene_process_joins_its_room_with_the_nkey(rooms, tmp_path):
    """`kinetre scene --nkey FILE` serves room a: its state reaches a client holding the same seed."""
    log = tmp_path / "scene.log"
    proc = subprocess.Popen([sys.executable, "-m", "kinetre.cli", "scene", "--nats", rooms["nats"].url, "--room", "a",
                             "--nkey", str(rooms["seed_a"]), "--nodes", "32"],
                            env=dict(os.environ, PYTHONUNBUFFERED="1"), stdout=open(log, "wb"), stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 120
        while "Kinetre scene" not in log.read_text():
            assert proc.poll() is None and time.monotonic() < deadline, log.read_text()[-2000:]
            time.sleep(0.2)

        async def state():
            bus = await NatsChannels.connect(rooms["nats"].url, "a", nkey=rooms["seed_a"])
            sub = bus.subscribe("kinetre.state")
            await bus.ready()
            frame = await sub.next(10)  # the scene's heartbeat
            await bus.close()
            return frame
        frame = asyncio.run(state())
        assert frame is not None and json.loads(frame.data)["meshes"][0]["nodes"] == 32
    finally:
        proc.terminate()
        proc.wait(10)
