"""Mesh placement (world = s R local + p), standing a mesh in metres, and resampling a take to a fixed rate."""
import numpy as np
import pytest

import kinetre
from kinetre.deform.pose import GraphPose
from kinetre.studio.placement import Placement, standing_mesh
from kinetre.studio.scene import TakeFrame, resample
from kinetre.wire.transforms import pack_transforms, unpack_transforms


def test_to_local_inverts_the_model_matrix(walk):
    p = Placement(1.7, (0.3, -0.2, 2.0), 0.9)
    sk = walk[5]
    local = p.to_local(sk)
    m = p.matrix()
    back = local.positions @ m[:3, :3].T + m[:3, 3]
    np.testing.assert_allclose(back, sk.positions, atol=1e-12)
    assert np.allclose(np.linalg.norm(local.positions[3] - local.positions[0]),
                       np.linalg.norm(sk.positions[3] - sk.positions[0]) / 1.7)


def test_placement_matrix_is_column_major_for_three(walk):
    p = Placement(2.0, (1.0, 2.0, 3.0), 0.0)
    elements = p.as_dict()["matrix"]
    assert elements[12:15] == [1.0, 2.0, 3.0] and elements[0] == 2.0


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_standing_mesh_is_1_6_m_tall_on_the_floor_whatever_the_units(body, scale):
    mesh = kinetre.Mesh(body.vertices * scale + 5.0, body.faces, body.normals)
    stood = standing_mesh(mesh)
    lo, hi = stood.bounds
    assert abs(lo[1]) < 1e-9 and abs(hi[1] - 1.6) < 1e-9
    assert abs(lo[0] + hi[0]) < 1e-9 and abs(lo[2] + hi[2]) < 1e-9
    np.testing.assert_allclose(stood.normals, body.normals, atol=1e-9)  # a similarity keeps normals


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
