"""The studio's avatar routes (studio/avatars.py) over HTTP: a humanoid gets a plan, a fox is refused with a
pointer to possession, a partial map drives what maps, too little is reported (422) and completed by a saved
map, and a take of page frames comes back as files."""
from __future__ import annotations

import pygltflib
import pytest
from starlette.applications import Starlette
from starlette.testclient import TestClient

from kinetre.avatar.load import load_avatar
from kinetre.studio.avatars import Shelf, avatar_routes


@pytest.fixture
def client():
    shelf = Shelf()
    with TestClient(Starlette(routes=avatar_routes(shelf))) as c:
        yield c
    shelf.close()


def upload(client, path, name=None):
    return client.post(f"/api/avatar?name={name or path.name}", content=path.read_bytes())


def test_a_humanoid_gets_a_plan_and_a_fox_is_refused(client, data_dir):
    r = upload(client, data_dir / "avatars" / "RiggedFigure.glb")
    assert r.status_code == 200
    body = r.json()
    assert body["missing"] == [] and body["plan"]["root"] == body["map"]["HipCenter"]
    assert client.get(body["url"]).content[:4] == b"glTF"
    r = upload(client, data_dir / "avatars" / "Fox.glb")
    assert r.status_code == 400
    assert r.json()["error"].startswith("Fox.glb: not an upright humanoid") and "kinetre animate" in r.json()["error"]
    r = client.post("/api/avatar?name=spot.obj", content=(data_dir / "meshes" / "spot.obj").read_bytes())
    assert r.status_code == 400 and "rigged .glb, .gltf or .vrm" in r.json()["error"]


def rehung(data_dir, tmp_path, name, moved):
    """CesiumMan with the skin joints `moved` (indices) hung on the scene root."""
    doc = pygltflib.GLTF2.load(str(data_dir / "avatars" / "CesiumMan.glb"))
    nodes = [doc.skins[0].joints[k] for k in moved]
    for node in doc.nodes:
        if node.children:
            node.children = [c for c in node.children if c not in nodes]
    doc.nodes[0].children = list(doc.nodes[0].children) + nodes
    path = tmp_path / name
    doc.save_binary(str(path))
    return path


def test_a_partial_map_drives_what_maps(client, data_dir, tmp_path):
    # CesiumMan with its arms hung on the scene root: the geometry no longer finds a chest with two arms,
    # the hips, torso and legs still drive it
    r = upload(client, rehung(data_dir, tmp_path, "armless.glb", [5, 6]))
    assert r.status_code == 200, r.json()
    body = r.json()
    assert {"ShoulderLeft", "ElbowLeft", "WristLeft"} <= set(body["missing"]) and body["plan"] is not None
    assert {"HipCenter", "HipLeft", "KneeLeft", "AnkleRight"} <= set(body["map"])


def test_too_little_is_reported_then_completed_by_the_editor(client, data_dir, tmp_path):
    names = load_avatar(data_dir / "avatars" / "CesiumMan.glb")
    # every joint hung on the scene root, no names: nothing to go by
    r = upload(client, rehung(data_dir, tmp_path, "flat.glb", range(1, len(names.joints))))
    assert r.status_code == 422
    body = r.json()
    assert "too little of the skeleton maps" in body["error"] and body["plan"] is None
    assert {"HipCenter", "ShoulderLeft", "ElbowLeft", "WristLeft"} <= set(body["missing"])
    table = {"HipCenter": "joint0", "ShoulderCenter": "joint3", "ShoulderLeft": "joint5", "ElbowLeft": "joint7",
             "WristLeft": "joint9", "ShoulderRight": "joint6", "ElbowRight": "joint8", "WristRight": "joint10",
             "HipLeft": "joint11", "KneeLeft": "joint13", "AnkleLeft": "joint15", "HipRight": "joint12",
             "KneeRight": "joint14", "AnkleRight": "joint16"}
    assert len(names.joints) == len(body["joints"])
    r = client.post(f"/api/avatars/{body['id']}/map", json={"kinect20": table})
    assert r.status_code == 200, r.json()
    done = r.json()
    assert done["missing"] == [] and done["how"]["ShoulderLeft"] == "file" and done["plan"] is not None
    saved = client.get(f"/api/avatars/{body['id']}/map").json()
    assert saved["avatar"] == "flat.glb" and saved["kinect20"]["ElbowLeft"] == "joint7"
    r = client.post(f"/api/avatars/{body['id']}/map", json={"kinect20": {"Elbow": "joint7"}})
    assert r.status_code == 400 and "'Elbow' is not a Kinect-20 joint" in r.json()["error"]


@pytest.mark.slow
def test_page_frames_come_back_as_a_take(client, data_dir, walk):
    body = upload(client, data_dir / "avatars" / "robot_quaternius.glb").json()
    frames = walk[:12]
    take = {"fps": 30, "positions": [[p if ok else None for p, ok in zip(f.positions.tolist(), f.tracked.tolist())]
                                      for f in frames], "tracked": [f.tracked.tolist() for f in frames]}
    take["positions"][3][7] = None
    take["tracked"][3][7] = False
    r = client.post(f"/api/avatars/{body['id']}/takes", json=take)
    assert r.status_code == 200, r.json()
    files = r.json()["files"]
    glb = client.get(files["glb"]).content
    assert glb[:4] == b"glTF" and client.get(files["bvh"]).content.startswith(b"HIERARCHY")
    r = client.post(f"/api/avatars/{body['id']}/takes", json={"fps": 30, "positions": [[[0, 0, 0]]], "tracked": [[True]]})
    assert r.status_code == 400 and "20 x 3" in r.json()["error"]
