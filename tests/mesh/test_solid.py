"""Points against a triangle surface: the winding number tells inside from outside (closed or not) and the
distance is the exact one to the nearest triangle."""
import numpy as np

import trimesh

from kinetre.mesh.solid import surface_distances, winding_numbers


def test_a_cube_winds_once_round_its_inside_and_not_round_its_outside():
    cube = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    points = np.array([[0.0, 0.0, 0.0], [0.9, -0.9, 0.5], [1.1, 0.0, 0.0], [3.0, 3.0, 3.0]])
    np.testing.assert_allclose(winding_numbers(points, cube.vertices, cube.faces), [1.0, 1.0, 0.0, 0.0],
                               atol=1e-9)


def test_an_open_box_winds_by_the_solid_angle_it_covers():
    cube = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    top = cube.triangles_center[:, 2] > 0.99
    open_box = cube.faces[~top]
    # seen from the centre each of the six sides covers a sixth of the sphere; five are left
    got = winding_numbers([[0.0, 0.0, 0.0]], cube.vertices, open_box)
    np.testing.assert_allclose(got, [5.0 / 6.0], atol=1e-9)
    assert got[0] >= 0.5  # still inside by the half threshold


def test_distances_to_a_cube_are_to_its_faces_edges_and_corners():
    cube = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    points = np.array([[3.0, 0.2, -0.3],     # in front of a face
                       [2.0, 2.0, 0.5],      # beside an edge
                       [2.0, 3.0, 3.0],      # off a corner
                       [0.0, 0.0, 0.4]])     # inside: to the nearest face
    np.testing.assert_allclose(surface_distances(points, cube.vertices, cube.faces),
                               [2.0, np.sqrt(2.0), np.sqrt(1.0 + 4.0 + 4.0), 0.6], atol=1e-12)
    assert np.isinf(surface_distances(points[:1], cube.vertices, cube.faces[:0])).all()
