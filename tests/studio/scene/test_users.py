"""The studio's live path: a camera user's body frames cleaned before the solve by default (smoothed, feet held
on the room's one floor) and measured by their meter, which the state message carries with what was applied;
mocap users (the sample player, VMC performers) as sent unless `contact` holds their feet; `--raw` cleans none."""
from __future__ import annotations

import numpy as np
import pytest

import kinetre
from kinetre.cli.main import main
from kinetre.studio.channels import Frame
from kinetre.studio.protocol import SkeletonFrame, sends_mocap
from kinetre.studio.scene.users import Users
from kinetre.studio.subjects import skeleton_subject
from synthetic import tpose

FPS = 30.0
FEET = [kinetre.KINECT20.index(n) for n in ("FootLeft", "FootRight")]


def frames(seed: int, x: float, n: int = 120, start: int = 0):
    rng = np.random.default_rng(seed)
    base = tpose(1.7, (x, 0.0, 0.0)).positions
    for k in range(start, start + n):
        pos = base + rng.normal(0.0, 0.01, base.shape)
        yield SkeletonFrame(k, 1000.0 * k / FPS, kinetre.Skeleton.from_positions(kinetre.KINECT20, pos))


def feed(users: Users, clients, possessing: bool = True, start: int = 0) -> dict:
    """Each client's frames, sent while it possesses a mesh (only then do its frames drive a solve)."""
    raw = {}
    for client, seed, x in clients:
        if possessing:
            user = users.user(client)
            user.bind, user.mesh = tpose(1.7, (x, 0.0, 0.0)), 1
        for f in frames(seed, x, start=start):
            users.receive(Frame(skeleton_subject(client), f.seq, f.t, b"", f))
            raw[client] = f.skeleton
    return raw


def test_camera_users_are_cleaned_on_one_floor_and_metered_mocap_as_sent():
    users = Users()  # the studio's default
    raw = feed(users, (("c1", 1, -0.5), ("ab12-c2p1", 2, 0.5), ("sample", 3, 0.0), ("vmc1", 4, 1.0)))
    a, b = users["c1"], users["ab12-c2p1"]
    for mocap in ("sample", "vmc1"):                                             # mocap: as sent, still metered
        assert users[mocap].cleaner is None and users[mocap].latest is raw[mocap]
        assert users[mocap].cleaning == [] and users[mocap].meter.figures()["lag_ms"] == 0.0
    assert a.latest is not raw["c1"] and b.cleaner.room is a.cleaner.room     # one floor for the room
    assert a.cleaning == ["smoothing", "contact"]
    assert np.abs(users.room.floor.above(a.latest.positions[FEET])).max() < 0.02
    q = a.meter.figures()
    assert q["frames"] in (90, 91) and q["jitter"] < q["jitter_tracked"] / 2 and q["held"] > 0.9
    assert abs(q["lag_ms"]) <= 1000 / FPS


def test_onlookers_are_neither_cleaned_nor_metered_until_they_possess():
    users = Users()
    raw = feed(users, (("c1", 1, 0.0),), possessing=False)
    c1 = users["c1"]
    assert c1.cleaner is None and c1.latest is raw["c1"] and c1.meter.figures()["frames"] == 0
    assert c1.cleaning == ["smoothing", "contact"]                              # what will clean it
    raw = feed(users, (("c1", 2, 0.0),), start=120)
    assert c1.cleaner is not None and c1.latest is not raw["c1"] and c1.meter.figures()["frames"] >= 90
    c1.let_go()
    assert c1.cleaner is None                                                  # the next possession starts afresh


def test_contact_holds_mocap_feet_unsmoothed_and_raw_cleans_nobody():
    users = Users(clean=True, contact=True)
    raw = feed(users, (("sample", 3, 0.0),))
    sample = users["sample"]
    assert sample.cleaning == ["contact"] and sample.meter.figures()["held"] > 0.9
    # feet held, the rest of the body as sent (no smoothing)
    arms = [kinetre.KINECT20.index(n) for n in ("Head", "ElbowLeft", "HandLeft", "HandRight")]
    assert np.allclose(sample.latest.positions[arms], raw["sample"].positions[arms], atol=1e-9)
    raw_users = Users(clean=False)
    raw = feed(raw_users, (("c1", 1, 0.0),))
    c1 = raw_users["c1"]
    assert c1.cleaner is None and c1.latest is raw["c1"] and c1.cleaning == []
    q = c1.meter.figures()                                                     # metered as tracked
    assert q["jitter"] == q["jitter_tracked"] > 0 and q["held"] == 0.0


def test_mocap_clients_are_told_by_name():
    assert sends_mocap("sample") and sends_mocap("vmc3")
    assert not any(sends_mocap(c) for c in ("c1", "ab12-c3", "c1p2", "vmc", "vmcx", "samples"))


@pytest.mark.parametrize("argv", [["studio", "--raw", "--contact", "--no-browser"],
                                  ["studio", "--remote-scene", "--raw", "--nats", "nats://127.0.0.1:1"],
                                  ["scene", "--raw", "--contact", "--nats", "nats://127.0.0.1:1"]])
def test_live_cleanup_options_that_cannot_apply_are_refused(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--raw" in err[0]
