"""Tracking models are checked by digest; person ids stay stable; takes carry people, hands and faces."""
import numpy as np
import pytest

from kinetre.errors import BadModelError
from kinetre.motion.models import MODELS, check_digest, model_path
from kinetre.motion.people import Tracks, assign_ids, main_person
from kinetre.motion.stream import read_stream, write_stream
from kinetre.motion.take import PersonFrame, crowd_take
from kinetre.skeleton.models import KINECT20, Skeleton


def test_a_corrupted_model_is_refused_naming_the_file_and_both_digests(tmp_path):
    bad = tmp_path / "hand_landmarker.task"
    bad.write_bytes(b"not the model")
    with pytest.raises(BadModelError) as e:
        model_path("hand_landmarker.task", dirs=(tmp_path,))
    msg = str(e.value)
    assert str(bad) in msg and MODELS["hand_landmarker.task"].sha256 in msg and "\n" not in msg
    import hashlib
    assert hashlib.sha256(b"not the model").hexdigest() in msg


def test_a_missing_model_names_the_make_target(tmp_path):
    with pytest.raises(BadModelError, match="make models"):
        model_path("pose_landmarker_full.task", dirs=(tmp_path,))
    with pytest.raises(BadModelError, match="unknown model"):
        model_path("nope.task")


def test_the_right_bytes_pass_the_digest_and_one_byte_more_does_not(monkeypatch, tmp_path):
    """A model file whose bytes hash to the published digest is the model, wherever it lies; a byte more is
    not (with a stand-in digest: the real models are tens of megabytes)."""
    from kinetre.motion import models
    data = b"a stand-in for the model's bytes"
    saved = models.MODELS["face_landmarker.task"]
    monkeypatch.setitem(models.MODELS, "face_landmarker.task",
                        models.ModelFile(saved.name, models.sha256_of(data), saved.sources))
    assert check_digest("face_landmarker.task", data, "x") is None
    (tmp_path / "face_landmarker.task").write_bytes(data)
    assert model_path("face_landmarker.task", dirs=(tmp_path,)) == tmp_path / "face_landmarker.task"
    with pytest.raises(BadModelError, match="x: sha256"):
        check_digest("face_landmarker.task", data + b"!", "x")


def test_ids_follow_people_who_cross_and_come_back_within_memory():
    state = Tracks()
    ids, state = assign_ids(state, [[100, 50], [300, 50]], [40, 40], 0.0)
    assert ids.tolist() == [0, 1]
    # listed in the other order and moved a little: the assignment, not the order, decides
    ids, state = assign_ids(state, [[290, 55], [110, 48]], [40, 40], 0.1)
    assert ids.tolist() == [1, 0]
    ids, state = assign_ids(state, [[112, 48]], [40, 40], 1.0)  # person 1 steps out
    assert ids.tolist() == [0]
    ids, state = assign_ids(state, [[115, 50], [285, 52]], [40, 40], 2.5)  # and back within 3 s
    assert ids.tolist() == [0, 1]
    ids, state = assign_ids(state, [[115, 50], [600, 52]], [40, 40], 2.6)  # far away: a new person
    assert ids.tolist() == [0, 2]
    ids, state = assign_ids(state, [[118, 50], [290, 50]], [40, 40], 5.55)  # 1 forgotten after 3 s
    assert ids.tolist() == [0, 3] and [k.id for k in state.tracks] == [0, 2, 3]


def follow(frames, middle=(320.0, 180.0)):
    """Ids and the main person after each frame of (t, centres) with 40-pixel bodies."""
    state, main, out = Tracks(), None, []
    for t, centres in frames:
        centres = np.array(centres, dtype=np.float64).reshape(-1, 2)
        ids, state = assign_ids(state, centres, np.full(len(centres), 40.0), t)
        main = main_person(main, state, ids, centres, middle)
        out.append((ids.tolist(), main))
    return out


@pytest.mark.parametrize("swap", [False, True])
def test_the_main_person_is_nearest_the_middle_at_first_sight_and_kept_by_id_whatever_the_order(swap):
    a, b = [300, 200], [500, 190]  # a nearer the middle (320, 180)
    both = [b, a] if swap else [a, b]
    out = follow([(0.0, both), (0.1, [b]), (0.2, [b]), (0.3, both[::-1]), (1.0, both)])
    ida = out[0][0][1 if swap else 0]
    assert [main for _, main in out] == [ida] * 5  # b, seen with a from the start, never takes over
    # a forgotten (3 s memory): b, in view, is followed
    out = follow([(0.0, both)] + [(0.5 * k, [b]) for k in range(1, 8)])
    assert [main for _, main in out] == [ida] * 7 + [1 - ida]


def test_someone_first_seen_after_the_main_person_vanished_is_followed():
    # one person jumps farther than 1.5 body sizes: a new id, followed at once
    out = follow([(0.0, [[100, 180]]), (0.1, [[100, 180]]), (0.2, [[300, 180]]), (0.3, [[300, 180]])])
    assert out == [([0], 0), ([0], 0), ([1], 1), ([1], 1)]
    # with one person in view all along beside the main one: the newcomer, not them
    out = follow([(0.0, [[100, 180], [600, 180]]), (0.1, [[600, 180], [300, 180]])])
    assert out == [([0, 1], 0), ([1, 2], 2)]
    assert follow([]) == [] and follow([(0.0, [])]) == [([], None)]


def test_people_hands_and_blendshapes_round_trip_and_old_fields_stay(tmp_path):
    rng = np.random.default_rng(1)
    main, people = [], []
    names = ("_neutral", "jawOpen")
    for i in range(3):
        a = Skeleton(KINECT20, rng.normal(size=(20, 3)), np.ones(20, bool))
        b = Skeleton(KINECT20, rng.normal(size=(20, 3)), np.ones(20, bool))
        hands = rng.normal(size=(2, 21, 3))
        hands[1] = np.nan  # right hand not found
        frame = (PersonFrame(4, a, hands, np.array([0.1, i / 3])),) + ((PersonFrame(7, b),) if i != 1 else ())
        main.append(a)
        people.append(frame)
    take = crowd_take(main, people, 30.0, "cam", names)
    path = tmp_path / "t.kinetre.jsonl"
    write_stream(path, take)
    back = read_stream(path)
    assert back.people == (4, 7) and back.blendshape_names == names
    assert np.array_equal(back.positions, take.positions)
    assert np.array_equal(back.hands, take.hands, equal_nan=True)
    assert np.array_equal(back.blendshapes, take.blendshapes, equal_nan=True)
    assert not back.crowd_tracked[1, 1].any() and back.crowd_tracked[2, 1].all()
    seven = back.person(7)
    assert np.array_equal(seven.positions[2], people[2][1].skeleton.positions)
    moved = back.transformed(2.0, translation=(1.0, 0.0, 0.0))
    assert np.allclose(moved.hands[0, 0, 0], 2 * take.hands[0, 0, 0] + [1, 0, 0])
    assert len(back.slice(1, 3).crowd_positions) == 2
