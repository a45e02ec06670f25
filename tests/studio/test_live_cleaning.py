"""The studio's live path: a user's body frames cleaned before the solve (smoothed, feet held on the room's
one floor) and measured by their meter, which the state message carries; the sample player's mocap as sent."""
from __future__ import annotations

import numpy as np

import kinetre
from kinetre.studio.channels import Frame
from kinetre.studio.protocol import SkeletonFrame
from kinetre.studio.scene.users import Users
from kinetre.studio.subjects import skeleton_subject
from synthetic import tpose

FPS = 30.0


def frames(seed: int, x: float, n: int = 120):
    rng = np.random.default_rng(seed)
    base = tpose(1.7, (x, 0.0, 0.0)).positions
    for k in range(n):
        pos = base + rng.normal(0.0, 0.01, base.shape)
        yield SkeletonFrame(k, 1000.0 * k / FPS, kinetre.Skeleton.from_positions(kinetre.KINECT20, pos))


def test_users_frames_are_cleaned_on_one_floor_and_metered():
    users = Users(clean=True, as_sent=("sample",))
    raw = {}
    for client, seed, x in (("a", 1, -0.5), ("b", 2, 0.5), ("sample", 3, 0.0)):
        for f in frames(seed, x):
            users.receive(Frame(skeleton_subject(client), f.seq, f.t, b"", f))
            raw[client] = f.skeleton
    a, b, sample = users["a"], users["b"], users["sample"]
    assert sample.cleaner is None and sample.latest is raw["sample"]          # mocap: as sent
    assert a.latest is not raw["a"] and b.cleaner.room is a.cleaner.room      # one floor for the room
    feet = [kinetre.KINECT20.index(n) for n in ("FootLeft", "FootRight")]
    assert np.abs(users.room.floor.above(a.latest.positions[feet])).max() < 0.02
    q = a.meter.figures()
    assert q["frames"] in (90, 91) and q["jitter"] < q["jitter_tracked"] / 2 and q["held"] > 0.9
    assert abs(q["lag_ms"]) <= 1000 / FPS
