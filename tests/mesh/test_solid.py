"""Points against a triangle surface: the winding number tells inside from outside (closed or not) and the
distance is the exact one to the nearest triangle."""
import numpy as np

import trimesh

from kinetre.mesh.solid import segment_crossings, surface_distances, winding_numbers


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


def test_a_segment_counts_the_surfaces_it_crosses_and_how_far_the_winding_number_falls_on_the_way():
    left = trimesh.creation.box(bounds=[[-3.0, -1.0, -1.0], [-1.0, 1.0, 1.0]])
    right = trimesh.creation.box(bounds=[[1.0, -1.0, -1.0], [3.0, 1.0, 1.0]])
    both = trimesh.util.concatenate([left, right])
    rng = np.random.default_rng(3)
    starts = np.column_stack([rng.uniform(-4, 4, 200), rng.uniform(-0.9, 0.9, 200), rng.uniform(-0.9, 0.9, 200)])
    ends = np.column_stack([rng.uniform(-4, 4, 200), rng.uniform(-0.9, 0.9, 200), rng.uniform(-0.9, 0.9, 200)])
    count, dip = segment_crossings(starts, ends, both.vertices, both.faces)
    # against the winding number sampled finely along each segment: a change at every wall, none between
    t = np.linspace(0.0, 1.0, 801)
    path = starts[:, None] + t[None, :, None] * (ends - starts)[:, None]
    wn = np.round(winding_numbers(path.reshape(-1, 3), both.vertices, both.faces).reshape(200, -1))
    np.testing.assert_array_equal(count, np.abs(np.diff(wn, axis=1)).sum(axis=1))
    np.testing.assert_array_equal(dip, (wn - wn[:, :1]).min(axis=1))
    assert (count == 2).any() and (dip == -1).any() and (count == 0).any()  # the cases are all there
