"""The scene's state message: every mesh listed alike (no first-mesh fields beside `meshes`), each user's
possession and attached joints routed to that user, the solve figures per mesh and the frame counters."""
import asyncio

import numpy as np
import pytest

from kinetre.studio.channels import Frame, Hub
from kinetre.studio.meshes import data_path, prepare_mesh
from kinetre.studio.protocol import SkeletonFrame
from kinetre.studio.scene import Scene

KEYS = {"type", "meshes", "users", "recording", "joint_map", "solve_ms", "solve_cpu_ms", "solve_cpu_ms_p99",
        "solves_stopped", "error", "skeleton_frames", "dropped"}


@pytest.fixture(scope="module")
def spot48():
    return prepare_mesh(str(data_path("spot.obj")), 48)


def test_the_state_lists_every_mesh_alike_and_routes_each_users_joints(spot48, walk, tmp_path):
    mesh, graph = spot48

    def send(scene, client, seq, k):
        scene.receive(Frame(f"kinetre.skeleton.{client}", seq, 1000.0 * seq / 30, b"",
                            SkeletonFrame(seq, 1000.0 * seq / 30, walk[k])))

    async def go():
        scene = Scene(Hub(), mesh, graph, "spot.obj", clean=False)
        second = scene.add_mesh(mesh, graph, "spot copy.obj")
        idle = scene.state()
        send(scene, "a", 1, 0)
        send(scene, "b", 1, 0)  # an onlooker: listed, possessing nothing
        scene.fit("a", second)
        await scene.possess("a", mesh_id=second)
        send(scene, "a", 2, 4)
        send(scene, "a", 3, 8)  # merged: frames 1 (bound to, never solved) and 2 replaced before a solve
        send(scene, "a", 2, 4)  # late: older than a's newest
        await scene.solve_once(mesh_id=second)
        scene.start_recording(tmp_path / "take")
        return scene.meshes.first.id, second, idle, scene.state()

    first, second, idle, state = asyncio.run(go())
    assert set(idle) == set(state) == KEYS  # only `meshes` describes meshes
    assert [m["id"] for m in state["meshes"]] == [first, second] and first != second
    for m in state["meshes"]:
        assert "attached" not in m  # routed to the users
        assert m["url"] == f"/api/mesh/{m['id']}"
        assert (m["nodes"], m["vertices"]) == (graph.node_count, len(mesh.vertices))
    one, two = state["meshes"]
    assert (one["possessors"], two["possessors"]) == ([], ["a"])
    assert one["solve_ms"] is None and two["solve_ms"] > 0  # solved once, the second mesh only
    users = {u["client"]: u for u in state["users"]}
    assert (users["a"]["possessing"], users["a"]["mesh"]) == (True, second)
    assert (users["b"]["possessing"], users["b"]["mesh"], users["b"]["attached"]) == (False, None, [])
    attached = users["a"]["attached"]
    assert len(attached) > 0 and all(isinstance(j, int) for j in attached)
    assert set(attached) <= set(range(len(walk[0].positions)))
    assert users["a"]["cleaning"] == users["b"]["cleaning"] == []  # raw: nobody cleaned
    assert (users["a"]["quality"]["frames"], users["b"]["quality"]["frames"]) == (2, 0)  # metered from possession on
    assert state["recording"] is True and idle["recording"] is False
    assert state["joint_map"] is None and state["error"] == ""
    assert state["dropped"] == {"merged": 2, "late": 1}
    assert state["solve_cpu_ms"] > 0 and state["solve_cpu_ms_p99"] >= state["solve_cpu_ms"]
    assert np.isfinite(state["solve_ms"]) and state["solves_stopped"] == 0
