"""A live solve yields to a newer frame inside the PCG loop (`live_stop.Yield`): the frame ends after
an accepted step with E lowered, `SolveReport.stopped` says so, and the next frames go on from the pose
reached and rejoin the uncut solve. Without the flag set, or before the frame has had its share, nothing
changes."""
import numpy as np
import pytest

import kinetre
from kinetre.deform.fast.live_stop import Yield, thread_cpu_time


@pytest.fixture(scope="module")
def walk_on_capsules(data_dir):
    from kinetre.motion.bvh import load_bvh
    from synthetic import capsule_body
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frames = [take.frame(i) for i in range(0, 160, 4)]
    return kinetre.build_graph(capsule_body(frames[0], radius=0.06), nodes=128, seed=0), frames


def run(graph, frames, stops):
    rig = kinetre.attach(graph, frames[0])
    reports = []
    for frame, stop in zip(frames[1:], stops):
        rig.solve(frame, stop=stop)
        reports.append(rig.last_report)
    return reports


def test_a_yielded_frame_ends_after_a_step_and_the_next_frames_catch_up(walk_on_capsules):
    graph, frames = walk_on_capsules
    count = len(frames) - 1
    waiting = Yield(np.ones(1, np.uint8), -np.inf)  # a newer frame waits, the share is spent
    full = run(graph, frames, [None] * count)
    # frames 17-20 (around the walk's stride turn) take 3-4 Gauss-Newton steps uncut
    cut_from, cut_to = 17, 21
    assert all(r.accepted >= 3 for r in full[cut_from:cut_to]) and not any(r.stopped for r in full)
    cut = run(graph, frames, [None] * cut_from + [waiting] * (cut_to - cut_from) + [None] * (count - cut_to))

    for a, b in zip(full[:cut_from], cut[:cut_from]):
        np.testing.assert_array_equal(a.x, b.x)
    for r, uncut in zip(cut[cut_from:cut_to], full[cut_from:cut_to]):
        assert r.stopped and r.accepted == 1 and r.cg_iterations > 0  # PCG, one accepted step
        assert r.energies[-1] < r.energies[0]  # E lowered…
        assert r.energy > uncut.energy  # …not converged
    for r in cut:
        assert np.all(np.diff(r.energies) < 0)
    # the next frames go on from the pose reached: within 1e-3 of the uncut solve's energy after two frames
    after = cut_to + 2
    assert not any(r.stopped for r in cut[cut_to:])
    rel = np.array([c.energy for c in cut[after:]]) / [f.energy for f in full[after:]] - 1
    assert np.abs(rel).max() < 1e-3, rel


def test_a_flag_not_set_or_a_share_not_spent_changes_nothing(walk_on_capsules):
    graph, frames = walk_on_capsules
    frames = frames[:24]
    full = run(graph, frames, [None] * 23)
    for stop in (Yield(np.zeros(1, np.uint8), -np.inf), Yield(np.ones(1, np.uint8), np.inf)):
        for a, b in zip(full, run(graph, frames, [stop] * 23)):
            np.testing.assert_array_equal(a.x, b.x)
            assert not b.stopped and a.energies == b.energies


def test_the_kernels_clock_is_the_threads_cpu_clock():
    import time
    before = time.thread_time()
    inside = thread_cpu_time()
    after = time.thread_time()
    assert before <= inside <= after


def test_yield_wants_one_byte():
    with pytest.raises(ValueError, match="uint8"):
        Yield(np.ones(1, bool), 0.0)
