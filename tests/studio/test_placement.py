"""Mesh placement (world = s R local + p) and standing a mesh in metres."""
import numpy as np
import pytest

import kinetre
from kinetre.studio.placement import Placement, standing_mesh



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
