"""A recorded take that swings the possessed mesh through a box tower, replayed through the page's physics
(web/src/physics/, bundled for node by esbuild): the same boxes fall on every run, at least half of them.

The take is made the way the studio makes one: the rig solves each skeleton frame (Gauss-Newton), the poses
go to `write_take_transforms` (what /api/record/stop writes), the mesh payload is the studio's own.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kinetre
from kinetre.physics.take import read_take_transforms, write_take_transforms
from kinetre.skeleton.models import KINECT20, Skeleton
from kinetre.studio.meshes import data_path, mesh_payload, prepare_mesh
from physics.node_replay import bundle, node_replay

FPS = 30.0


def swing_take(mesh, graph, frames: int = 40) -> list:
    """Poses of a skeleton inside the mesh that slides 1.6 m along +x while yawing 50°, solved by the rig."""
    lo, hi = mesh.bounds
    axis = int(np.argmax(hi - lo))
    order = np.argsort(graph.nodes[:, axis])
    picks = graph.nodes[order[np.linspace(0, len(order) - 1, 20).astype(int)]]
    rig = kinetre.attach(graph, Skeleton(KINECT20, picks, np.ones(20, bool)))
    centre = picks.mean(axis=0)
    poses = []
    for k in range(frames):
        s = k / (frames - 1)
        rot = Rotation.from_euler("y", -50 * s, degrees=True).as_matrix()
        moved = (picks - centre) @ rot.T + centre + [1.6 * s, 0.0, 0.0]
        poses.append(rig.solve(Skeleton(KINECT20, moved, np.ones(20, bool))))
    return poses


@pytest.fixture(scope="module")
def take(tmp_path_factory):
    folder = tmp_path_factory.mktemp("physics")
    mesh, graph = prepare_mesh(str(data_path("spot.obj")), 128)  # the studio's own sample mesh, standing
    poses = swing_take(mesh, graph)
    write_take_transforms(folder / "take.transforms", graph, poses, FPS)
    (folder / "mesh.json").write_text(json.dumps(mesh_payload(mesh, graph, 1, "spot.obj")))
    script = bundle(folder / "replay_take.mjs")
    return folder, script, mesh, graph, poses


def replay(folder: Path, script: Path, runs: int = 2) -> dict:
    return node_replay(script, folder / "mesh.json", folder / "take.transforms", FPS, runs)


def test_take_transforms_round_trip(take):
    folder, _, _, graph, poses = take
    m = read_take_transforms(folder / "take.transforms")
    assert m.shape == (len(poses), graph.node_count, 4, 4)
    assert np.allclose(m[-1], poses[-1].node_matrices(graph.nodes), atol=1e-5)


@pytest.mark.slow
def test_swing_knocks_down_the_same_boxes_every_run(take):
    folder, script, *_ = take
    first, second = replay(folder, script), replay(folder, script)  # two node processes, two worlds each
    runs = first["runs"] + second["runs"]
    down = [r["knockedDown"] for r in runs]
    boxes = runs[0]["boxes"]
    print(f"\nboxes knocked down per run: {down} of {boxes}; spheres {runs[0]['spheres']}, "
          f"{runs[0]['steps']} steps")
    assert boxes == 20 and first["frames"] == 40
    assert len(set(down)) == 1 and down[0] >= boxes / 2
    assert all(r["states"] == runs[0]["states"] for r in runs)  # bit-identical worlds, not just equal counts


@pytest.mark.slow
def test_a_mesh_at_rest_knocks_nothing_down(take, tmp_path):
    folder, script, mesh, graph, _ = take
    still = tmp_path / "still"
    still.mkdir()
    write_take_transforms(still / "take.transforms", graph, [kinetre.GraphPose.identity(graph.node_count)] * 40, FPS)
    (still / "mesh.json").write_text((folder / "mesh.json").read_text())
    r = replay(still, script, runs=1)["runs"][0]
    assert r["boxes"] == 20 and r["knockedDown"] == 0  # the tower stands beside the mesh, untouched


def test_a_truncated_take_names_the_file(take, tmp_path):
    folder, *_ = take
    data = (folder / "take.transforms").read_bytes()
    bad = tmp_path / "cut.transforms"
    bad.write_bytes(data[: len(data) // 2 + 7])
    with pytest.raises(kinetre.BadMotionError, match="cut.transforms"):
        read_take_transforms(bad)
    bad.write_bytes(b"KTX2" + data[4:])
    with pytest.raises(kinetre.BadMotionError, match="frame 0 is not a transform block"):
        read_take_transforms(bad)
