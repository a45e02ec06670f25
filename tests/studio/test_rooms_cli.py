"""`kinetre rooms`: the nats-server configuration a user writes from the command line, a token room and an
nkey room, started on a real nats-server: each room's credentials get in, and only into that room."""
import asyncio
import os
import subprocess

import pytest
from studio.nats_server import free_port, nats_binary

from kinetre.cli import main
from kinetre.studio.natsbus import NatsChannels, NetworkError, nkey_public


@pytest.mark.slow  # a real nats-server
def test_rooms_command_writes_a_working_configuration(tmp_path, capsys):
    conf, seed, port = tmp_path / "rooms.conf", tmp_path / "stage.nk", free_port()
    assert main(["rooms", "class=tok-7f3a", f"stage=@{seed}", "-o", str(conf), "--port", str(port)]) == 0
    public = nkey_public(seed)
    out = capsys.readouterr().out
    assert f"new seed written to {seed}" in out and public in out
    assert oct(os.stat(seed).st_mode & 0o777) == "0o600"
    text = conf.read_text()
    assert f"listen: 127.0.0.1:{port}" in text and f'nkey: "{public}"' in text and seed.read_text().strip() not in text
    # a second run keeps the existing seed: the room's key does not change under its studios
    assert main(["rooms", "class=tok-7f3a", f"stage=@{seed}", "-o", str(conf), "--port", str(port), "-q"]) == 0
    assert nkey_public(seed) == public and conf.read_text() == text

    server = subprocess.Popen([nats_binary(), "-c", str(conf)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"nats://127.0.0.1:{port}"

    async def go():
        for _ in range(100):  # the server is up when it answers
            try:
                stage = await NatsChannels.connect(url, "stage", nkey=seed)
                break
            except NetworkError:
                await asyncio.sleep(0.1)
        klass = await NatsChannels.connect(url, "class", "tok-7f3a")
        for bus in (stage, klass):
            bus.subscribe("kinetre.transforms")
            await bus.ready()  # each in its own room
        with pytest.raises(NetworkError) as token_elsewhere:  # the class token is no password of the stage
            await NatsChannels.connect(url, "stage", "tok-7f3a")
        spy = await NatsChannels.connect(url, "class", nkey=seed)  # the stage's key, the class's subjects
        spy.subscribe("kinetre.transforms")
        with pytest.raises(NetworkError, match="ermissions violation"):
            await spy.ready()
        for bus in (stage, klass, spy):
            await bus.close()
        return str(token_elsewhere.value)

    try:
        refused = asyncio.run(go())
    finally:
        server.kill()
        server.wait(10)
    assert "refused" in refused, refused


@pytest.mark.parametrize("spec, message", [("stage", "ROOM=TOKEN or ROOM=@SEED_FILE"),
                                           ("stage=", "ROOM=TOKEN or ROOM=@SEED_FILE"),
                                           ("bad room=tok", "room"),
                                           ("bad room=@{new}", "room"),
                                           ("stage=@{notes}", "not an nkey seed")])
def test_rooms_command_refuses_bad_input(tmp_path, capsys, spec, message):
    notes = tmp_path / "notes.txt"
    notes.write_text("hello\n")
    assert main(["rooms", spec.format(notes=notes, new=tmp_path / "new.nk"), "-o", str(tmp_path / "r.conf")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "r.conf").exists() and not (tmp_path / "new.nk").exists()
