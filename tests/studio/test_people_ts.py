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
    for first_order in (0, 1):
        frames = []
        for k in range(20):
            a, b = [0.28 + 0.02 * (k % 3), 0.6], [0.73 - 0.02 * (k % 2), 0.6]
            frames.append((100.0 * k, [a, b] if (k + first_order) % 3 else [b, a]))
        out = run(bundle, frames)
        lefts = []
        for (t, centres), o in zip(frames, out):
            assert sorted(o["ids"]) == [1, 2] and o["inView"] == [1, 2]
            lefts.append(o["ids"][0] if centres[0][0] < centres[1][0] else o["ids"][1])
        assert lefts == [lefts[0]] * len(frames)  # the one on the left keeps one id all along
        left, right = lefts[0], 3 - lefts[0]
        # the one nearer the middle at first sight (the left one, 0.20 from it against 0.23) drives the page's
        # channel all along, whichever the landmarker listed first
        assert [o["main"] for o in out] == [left] * len(frames)
        last = out[-1]
        assert last["user"][left - 1] == "c7" and last["user"][right - 1] == f"c7p{right}"
        # person `right` is sent as its own user, seq counting up
        sent = [m for o in out for m in o["sent"]]
        assert {m["person"] for m in sent} == {right} and [m["seq"] for m in sent] == list(range(1, 21))
        assert last["possess"] == [{"type": "possess", "person": right, "subset": None}]
        # a hand puppet: the hand possesses, no body subset goes with it
        assert last["possessByHand"] == [{"type": "possess", "person": right, "subset": None, "hand": "right"}]
        assert last["release"] == [{"type": "release", "person": right}]


def test_a_person_who_steps_out_keeps_their_id_for_a_while_then_a_newcomer_gets_a_new_one(bundle):
    a, b = [0.32, 0.6], [0.7, 0.6]  # a nearer the middle: the page's own user
    frames = [(0.0, [a, b]), (100.0, [a, b]), (200.0, [a])]  # the one on the right steps out ...
    frames += [(3200.0, [a, [0.75, 0.6]])]  # ... and is back 3 s later, a little further right
    frames += [(3300.0, [a])] + [(3300.0 + 1000.0 * k, [a]) for k in range(1, 13)]  # gone for 12 s
    frames += [(15400.0, [a, [0.7, 0.6]])]  # someone there again: a new person
    out = run(bundle, frames)
    assert out[2]["inView"] == [1] and out[3]["ids"] == [1, 2]
    assert out[-1]["ids"] == [1, 3] and out[-1]["user"] == ["c7", "c7p3"]
    assert out[-1]["release"] == [{"type": "release", "person": 2}, {"type": "release", "person": 3}]


@pytest.mark.parametrize("swap", [False, True])
def test_the_main_person_is_the_one_nearest_the_middle_at_first_sight_and_keeps_it_while_remembered(bundle, swap):
    a, b = [0.45, 0.6], [0.8, 0.6]  # a nearer the middle
    order = (lambda *c: list(reversed(c))) if swap else (lambda *c: list(c))
    frames = [(0.0, order(a, b)), (100.0, [b]), (200.0, [b]), (300.0, order(a, b))]  # a missed, then back
    out = run(bundle, frames)
    ida = out[0]["ids"][1 if swap else 0]
    idb = 3 - ida
    assert [o["main"] for o in out] == [ida] * 4  # b never takes the page's channel
    assert out[0]["user"][ida - 1] == "c7" and out[0]["user"][idb - 1] == f"c7p{idb}"
    # while a is missed, b is still sent as their own user and the page's own channel gets nothing
    assert [o["sent"] for o in out[1:3]] == [[{"person": idb, "seq": 2, "tracked": 20}],
                                              [{"person": idb, "seq": 3, "tracked": 20}]]
    assert out[1]["mainSeen"] is False and out[3]["mainSeen"] is True
    # and Possess, pressed while one of them is missed, still reaches b
    late = run(bundle, [(0.0, order(a, b)), (100.0, [a])])
    assert late[1]["possess"] == [{"type": "possess", "person": 3 - late[0]["ids"][1 if swap else 0], "subset": None}]


def test_the_main_person_forgotten_passes_the_channel_to_the_one_in_view(bundle):
    a, b = [0.45, 0.6], [0.8, 0.6]
    frames = [(0.0, [a, b])] + [(1000.0 * k, [b]) for k in range(1, 12)]  # a gone for 11 s: forgotten after 10
    out = run(bundle, frames)
    assert [o["main"] for o in out] == [1] * 11 + [2]
    assert out[-1]["user"] == ["c7"] and out[-1]["sent"] == [] and out[-1]["mainSeen"] is True


def test_a_person_first_seen_after_the_main_one_vanished_takes_over_the_channel(bundle):
    # one person jumps farther than the tracker follows: a new id, and the page follows them at once
    out = run(bundle, [(0.0, [[0.3, 0.6]]), (100.0, [[0.3, 0.6]]), (200.0, [[0.6, 0.6]]), (300.0, [[0.6, 0.6]])])
    assert [o["ids"] for o in out] == [[1], [1], [2], [2]] and [o["main"] for o in out] == [1, 1, 2, 2]
    assert all(o["sent"] == [] and o["mainSeen"] for o in out)
    # someone who was in view with the main person all along does not: each keeps their own user
    out = run(bundle, [(0.0, [[0.3, 0.6], [0.9, 0.6]]), (100.0, [[0.9, 0.6], [0.6, 0.6]])])
    assert out[1]["ids"] == [2, 3] and out[1]["main"] == 3


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
