"""The page's people (web/src/app/People.ts and capture/PersonTracks.ts, run under node): stable ids for the
people in one camera, one studio user each, and what Possess and Release send for them."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from web_bundle import esbuild

RUNNER = Path(__file__).resolve().parent / "node" / "people_ts.mjs"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    out = tmp_path_factory.mktemp("ts") / "people.mjs"
    esbuild(["app/People.ts"], f"--outfile={out}")
    return out


def run(bundle, frames) -> list[dict]:
    fixture = {"frames": [{"t": t, "width": 640, "height": 360, "centres": c} for t, c in frames]}
    out = subprocess.run(["node", str(RUNNER), str(bundle)], input=json.dumps(fixture), capture_output=True,
                         text=True, timeout=120, check=True)
    return json.loads(out.stdout)


def test_two_people_keep_their_ids_whatever_order_they_are_detected_in(bundle):
    # two dancers 0.45 image widths apart, swaying 0.02 a frame; the landmarker lists them in either order
    frames = []
    for k in range(20):
        a, b = [0.28 + 0.02 * (k % 3), 0.6], [0.73 - 0.02 * (k % 2), 0.6]
        frames.append((100.0 * k, [a, b] if k % 3 else [b, a]))
    out = run(bundle, frames)
    lefts = []
    for (t, centres), o in zip(frames, out):
        assert sorted(o["ids"]) == [1, 2] and o["inView"] == [1, 2]
        lefts.append(o["ids"][0] if centres[0][0] < centres[1][0] else o["ids"][1])
    assert lefts == [lefts[0]] * len(frames)  # the one on the left keeps one id all along
    last = out[-1]
    assert last["main"] == 1 and last["user"] == ["c7", "c7p2"]  # the first seen drives the page's channel
    # the page's own channel carries person 1; person 2 is sent as its own user, seq counting up
    sent = [m for o in out for m in o["sent"]]
    assert {m["person"] for m in sent} == {2} and [m["seq"] for m in sent] == list(range(1, 21))
    assert last["possess"] == [{"type": "possess", "person": 2, "subset": None}]
    # a hand puppet: the hand possesses, no body subset goes with it
    assert last["possessByHand"] == [{"type": "possess", "person": 2, "subset": None, "hand": "right"}]
    assert last["release"] == [{"type": "release", "person": 2}]


def test_a_person_who_steps_out_keeps_their_id_for_a_while_then_a_newcomer_gets_a_new_one(bundle):
    a, b = [0.3, 0.6], [0.7, 0.6]
    frames = [(0.0, [a, b]), (100.0, [a, b]), (200.0, [a])]  # the one on the right steps out ...
    frames += [(3200.0, [a, [0.75, 0.6]])]  # ... and is back 3 s later, a little further right
    frames += [(3300.0, [a])] + [(3300.0 + 1000.0 * k, [a]) for k in range(1, 13)]  # gone for 12 s
    frames += [(15400.0, [a, [0.7, 0.6]])]  # someone there again: a new person
    out = run(bundle, frames)
    assert out[2]["inView"] == [1] and out[3]["ids"] == [1, 2]
    assert out[-1]["ids"] == [1, 3] and out[-1]["user"] == ["c7", "c7p3"]
    assert out[-1]["release"] == [{"type": "release", "person": 2}, {"type": "release", "person": 3}]


def test_the_main_person_drives_the_pages_channel_while_in_view(bundle):
    a, b = [0.3, 0.6], [0.7, 0.6]
    out = run(bundle, [(0.0, [a]), (100.0, [a, b]), (200.0, [b]), (300.0, [a, b])])
    assert [o["main"] for o in out] == [1, 1, 2, 2]  # 1 missed: 2 takes the channel, and keeps it
    assert out[1]["sent"] == [{"person": 2, "seq": 1, "tracked": 20}] and out[2]["sent"] == []
    assert out[3]["sent"] == [{"person": 1, "seq": 1, "tracked": 20}] and out[3]["user"] == ["c7p1", "c7"]


def test_one_person_reported_twice_is_one_person(bundle):
    # the landmarker's duplicate of the person on the left, a hair off: not a third person, no new id
    out = run(bundle, [(0.0, [[0.3, 0.6], [0.7, 0.6]]), (100.0, [[0.3, 0.6], [0.7, 0.6], [0.302, 0.61]]),
                       (200.0, [[0.301, 0.6], [0.7, 0.6]])])
    assert [sorted(o["ids"]) for o in out] == [[1, 2], [1, 2], [1, 2]]
    assert out[1]["ids"] == out[0]["ids"] == out[2]["ids"]


def test_a_person_keeps_their_current_track_over_an_older_one_nearby(bundle):
    # a jump opened a second track; 2 s on, the person stands a little nearer the old one than their own
    out = run(bundle, [(0.0, [[0.3, 0.6]]), (100.0, [[0.5, 0.6]]), (2000.0, [[0.5, 0.6]]), (2100.0, [[0.38, 0.6]])])
    assert [o["ids"] for o in out] == [[1], [2], [2], [2]]
