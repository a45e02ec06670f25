"""Takes: resampling a take to a fixed rate, and the transform blocks a take's frames go out as."""
import numpy as np

from kinetre.deform.pose import GraphPose
from kinetre.studio.scene import TakeFrame, resample
from kinetre.wire.transforms import pack_transforms, unpack_transforms


def test_resample_holds_the_newest_frame_at_each_tick():
    poses = [GraphPose.identity(2) for _ in range(4)]
    take = [TakeFrame(t, p) for t, p in zip([0.0, 10.0, 70.0, 100.0], poses)]
    out = resample(take, 30.0)  # ticks at 0, 33.3, 66.7, 100 ms
    assert [f.t for f in out] == [0.0, 10.0, 10.0, 100.0]
    assert resample([], 30.0) == []


def test_transform_blocks_round_trip():
    rng = np.random.default_rng(0)
    m = np.tile(np.eye(4), (7, 1, 1))
    m[:, :3, :] = rng.normal(size=(7, 3, 4))
    seq, mesh_id, t_source, t_out, back = unpack_transforms(pack_transforms(42, 3, m, 1.5e12, 1.6e12))
    assert (seq, mesh_id, t_source, t_out) == (42, 3, 1.5e12, 1.6e12)
    np.testing.assert_allclose(back, m, atol=1e-6)
