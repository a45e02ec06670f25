import numpy as np

from kinetre.scan.recent import RecentFrames, remembered


def test_recent_frames_make_each_result_once_per_frame_and_forget_the_oldest():
    made = []

    def make(tag):
        return lambda: made.append(tag) or len(made)

    recent = RecentFrames(size=2)
    a, b = np.zeros(3), np.zeros(3)          # equal values, different frames
    assert recent.get(("orb", a, 1), make("a1")) == 1
    assert recent.get(("orb", a, 1), make("again")) == 1    # the same arrays and options: made once
    assert recent.get(("orb", b, 1), make("b1")) == 2       # identity, not equal values, names a frame
    assert recent.get(("orb", a, 2), make("a2")) == 3       # other options: another result
    assert recent.get(("orb", b, 1), make("again")) == 2
    assert recent.get(("orb", a, 1), make("a1 again")) == 4  # dropped as the oldest beyond size 2
    assert remembered(None, ("orb", a, 2), make("no memo")) == 5
    assert made == ["a1", "b1", "a2", "a1 again", "no memo"]
