"""Up axis on load: a mesh stored +Z up is stood on its feet; +Y up wins whenever the mesh rests on it."""
import numpy as np
import pytest

from kinetre.mesh.load import load_mesh
from kinetre.mesh.mesh import Mesh
from kinetre.mesh.upright import find_upright, rotation_to_y_up, support_margin, turned

# a quarter turn about +X: what a +Y-up mesh becomes when a tool stores it +Z up
Y_TO_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def stored_z_up(mesh: Mesh) -> Mesh:
    return Mesh(vertices=mesh.vertices @ Y_TO_Z.T, faces=mesh.faces, normals=mesh.normals @ Y_TO_Z.T)


def box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], float)
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return corners, faces


def table() -> tuple[np.ndarray, np.ndarray]:
    """A table top on one leg at a corner: +Y up it topples (its centre is far from the leg); turned with
    its +Z up it lies on its side, the top's long edge and the leg on the floor, and rests."""
    top_v, top_f = box((0, 1.0, 0), (2, 1.1, 0.2))
    leg_v, leg_f = box((0, 0, 0), (0.1, 1.0, 0.1))
    return np.vstack([top_v, leg_v]), np.vstack([top_f, leg_f + len(top_v)])


def test_the_margin_is_the_centres_distance_inside_the_floor_contact():
    v, f = box((-1, 0, -1), (1, 1, 1))  # a cube on the floor: the centre 1 from every edge, size 2
    assert support_margin(v, f) == pytest.approx(0.5)
    v, f = table()
    assert support_margin(v, f) < 0  # the centre (x = 1) is far outside the leg's 10 cm square


def test_a_shape_that_topples_with_y_up_is_stood_on_z():
    v, f = table()
    found = find_upright(Mesh(vertices=v, faces=f, normals=np.zeros_like(v)), "table.stl")
    assert found.up == "z" and found.margins["y"] < 0 <= found.margins["z"]  # on its side, it rests
    upside_down = v @ Y_TO_Z.T @ Y_TO_Z.T  # a half turn: on its top, it rests with +Y up and stays so
    assert find_upright(Mesh(vertices=upside_down, faces=f, normals=np.zeros_like(v)), "table.stl").up == "y"


@pytest.mark.parametrize("name", ["spot.obj", "armadillo.obj", "teapot.obj"])
def test_public_meshes_stored_z_up_stand_again(data_dir, name):
    mesh = load_mesh(data_dir / "meshes" / name)
    assert find_upright(mesh, name).up == "y"  # as published: +Y up, left alone
    z_up = stored_z_up(mesh)
    found = find_upright(z_up, name.replace(".obj", ".ply"))
    assert found.up == "z" and found.margins["y"] < 0 <= found.margins["z"]
    np.testing.assert_allclose(turned(z_up, "z").vertices, mesh.vertices, atol=1e-9)


def test_gltf_is_y_up_by_its_specification(data_dir):
    z_up = stored_z_up(load_mesh(data_dir / "meshes" / "spot.obj"))
    assert find_upright(z_up, "spot.glb").up == "y"
    with pytest.raises(ValueError, match="up must be 'y' or 'z'"):
        rotation_to_y_up("x")
