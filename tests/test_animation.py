"""`kinetre.animate` stands a mesh stored +Z up on its feet before fitting, and drives it as if it had been
stored +Y up; `up="y"` takes the file as it is."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import kinetre
from kinetre.errors import BadSettingsError

# a quarter turn about +X: what a +Y-up mesh becomes when a tool stores it +Z up
Y_TO_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def written(path, vertices, faces):
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    return kinetre.load_mesh(path)


@pytest.fixture(scope="module")
def spot_twice(data_dir, tmp_path_factory):
    """Spot as published (+Y up) and stored +Z up, both as PLY (no file convention: the shape decides)."""
    folder = tmp_path_factory.mktemp("upright")
    spot = kinetre.load_mesh(data_dir / "meshes" / "spot.obj")
    return (written(folder / "standing.ply", spot.vertices, spot.faces),
            written(folder / "lying.ply", spot.vertices @ Y_TO_Z.T, spot.faces))


@pytest.fixture(scope="module")
def walk(data_dir):
    return kinetre.load_take(data_dir / "bvh" / "cmu_12_01_walk.bvh").slice(0, 4)


@pytest.mark.slow
def test_a_mesh_stored_z_up_deforms_as_the_upright_original(spot_twice, walk):
    standing, lying = spot_twice
    settings = kinetre.AnimateSettings(nodes=48)
    upright, stood = kinetre.animate(standing, walk, settings), kinetre.animate(lying, walk, settings)
    assert upright.upright.up == "y" and stood.upright.up == "z"
    assert stood.upright.reason == "stood up: +Z up, it stands better than with +Y up"  # on its side, it rests
    height = np.ptp(standing.vertices[:, 1])
    np.testing.assert_allclose(stood.mesh.vertices, standing.vertices, atol=1e-9 * height)  # written standing
    moved = 0.0
    for a, b in zip(upright.poses, stood.poses):
        got, want = kinetre.skin(stood.mesh, stood.graph, b), kinetre.skin(upright.mesh, upright.graph, a)
        assert np.abs(got - want).max() < 1e-6 * height
        moved = max(moved, np.abs(want - standing.vertices).max())
    assert moved > 0.1 * height  # the walk deforms the mesh: the comparison is not of two rest poses


def test_up_y_takes_the_file_as_it_is(spot_twice, walk):
    _, lying = spot_twice
    kept = kinetre.animate(lying, walk, kinetre.AnimateSettings(nodes=48, up="y", solve=False))
    assert kept.upright.up == "y" and kept.upright.reason == "+Y up, as asked"
    np.testing.assert_array_equal(kept.mesh.vertices, lying.vertices)
    # the skeleton is sized to the lying mesh's height, its depth when standing
    assert kept.take.frame(0).height == pytest.approx(np.ptp(lying.vertices[:, 1]), rel=1e-9)
    with pytest.raises(BadSettingsError, match="--up must be one of auto, y, z, x, -x, -y, -z, got 'w'"):
        kinetre.animate(lying, walk, kinetre.AnimateSettings(nodes=48, up="w"))


def test_a_figure_on_rounded_feet_stays_upright():
    from kinetre.mesh.upright import find_upright
    from kinetre.motion.take import Take
    from kinetre.skeleton.models import KINECT20, Skeleton, SkeletonModel
    from synthetic import capsule_body, tpose

    stick = SkeletonModel("stick", KINECT20.joints, KINECT20.parents)
    bind = tpose(1.0, (0.0, 0.5, 0.0)).positions
    take = Take(stick, bind[None], np.ones((1, len(bind)), bool), 30.0, "stick")
    body = capsule_body(Skeleton(stick, bind, take.tracked[0]), radius=0.03)
    # it topples on its round feet, and on its back, arms spread, it lies flat: no side stands clearly
    assert find_upright(body).up == "y"
    result = kinetre.animate(body, take, kinetre.AnimateSettings(nodes=48, yaw=0.0, solve=False))
    assert result.upright.up == "y"
    np.testing.assert_array_equal(result.mesh.vertices, body.vertices)


@pytest.mark.parametrize("bad, message", [({"solver": "local_global"}, "solver must be one of pcg, exact or None"),
                                          ({"nodes": 1}, "--nodes must be an integer of at least 2"),
                                          ({"fit": "width"}, "fit must be one of"),
                                          ({"up": "w"}, "--up must be one of"),
                                          ({"bind_frame": 1.5}, "--bind-frame must be an integer")])
def test_a_setting_no_input_can_use_is_refused_when_made(bad, message):
    """Refused at construction, before any graph is built: a KinetreError (the CLI's exit 2), not a late
    ValueError."""
    with pytest.raises(BadSettingsError, match=message):
        kinetre.AnimateSettings(**bad)
