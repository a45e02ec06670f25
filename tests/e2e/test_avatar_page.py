"""An avatar in the studio page (real Chromium, tests/e2e/driver_avatar.mjs): uploaded like a mesh, driven by
the sample motion, skinned by three.js exactly like our numpy LBS, recorded to a validator-clean GLB, its
bone map edited and saved next to it, then driven by the webcam (a dancer on the fake camera); a fox is refused as an avatar and loaded for possession instead.
An avatar's fingers and expressions follow the hands and face of a photo played as the camera
(tests/e2e/driver_hands.mjs)."""
from __future__ import annotations

from pathlib import Path

import httpx
import numpy as np
from PIL import Image
from avatar.synthetic import MORPHS, write_rigged_avatar
from e2e.fake_camera import y4m
from e2e.node_driver import run_driver
from studio.conftest import start_server

from export.takes import validate_gltf
from kinetre.avatar.bonemap import map_bones
from kinetre.avatar.load import load_avatar
from kinetre.avatar.retarget import plan_retarget, retarget
from kinetre.avatar.skin import bind_bounds, skin_avatar
from kinetre.motion.bvh import load_bvh

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def test_an_avatar_in_the_studio_page(data_dir, tmp_path):
    assert (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file(), "run `make web` first"
    take = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    frame = take.frame(200)
    cesium = data_dir / "avatars" / "CesiumMan.glb"
    config = {"avatar": str(cesium), "fox": str(data_dir / "avatars" / "Fox.glb"),
              "frame": {"positions": frame.positions.tolist(), "tracked": frame.tracked.tolist()},
              "shoulderCenter": "joint2", "artifacts": str(HERE / "artifacts"),
              "video": str(ROOT / ".." / "shared" / "data" / "video" / "pose_1_320x240_30fps.y4m")}
    proc, url = start_server(sample_motion=True)
    try:
        result = run_driver("driver_avatar.mjs", {**config, "url": url + "/"}, 600)
        downloads = dict(result["downloads"])
        files = {k: httpx.get(url + downloads[k], timeout=30).content for k in ("avatar GLB", "avatar BVH")}
        saved_map = httpx.get(url + "/" + result["mapLink"], timeout=30).json()
    finally:
        proc.terminate()
        proc.wait(60)

    steps = {s["step"]: s for s in result["steps"]}
    assert steps["avatar driven"]["source"] == "sample"
    assert result["spread"] > 0.05                     # the walk moves the avatar's vertices (metres)
    assert steps["camera drives the avatar"]["source"] == "me" and result["cameraSpread"] > 0.05

    # the page's three.js skinning of the given frame = our retarget + numpy LBS, placed like the page
    avatar = load_avatar(cesium)
    plan = plan_retarget(avatar, map_bones(avatar))
    motion = retarget(plan, frame.positions[None], frame.tracked[None])
    ours = skin_avatar(avatar, motion.world)[0][0]
    model = np.array(result["skinned"]["model"]).reshape(4, 4).T      # three.js elements are column-major
    n = len(ours)
    index = [int(i * n / 48) for i in range(48)]
    expected = ours[index] @ model[:3, :3].T + model[:3, 3]
    lo, hi = bind_bounds(avatar)
    diagonal = np.linalg.norm(hi - lo) * np.cbrt(abs(np.linalg.det(model[:3, :3])))
    err = np.linalg.norm(np.array(result["skinned"]["vertices"]) - expected, axis=1).max()
    assert err <= 1e-3 * diagonal, (err, diagonal)

    glb = tmp_path / "take.glb"
    glb.write_bytes(files["avatar GLB"])
    report = validate_gltf(glb)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    assert report["info"]["animationCount"] == 1
    assert files["avatar BVH"].startswith(b"HIERARCHY")
    assert result["mapped"]["ShoulderCenter"] == "file" and saved_map["kinect20"]["ShoulderCenter"] == "joint2"
    assert "not an upright humanoid" in result["foxMessage"] and "possess" in result["foxMessage"]
    assert result["meshAfterFox"] == "Fox.glb"


def quaternion_degrees(a, b) -> np.ndarray:
    """Angles (degrees) between rotations given as rows of unit quaternions (x, y, z, w)."""
    dot = np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1))
    return np.degrees(2 * np.arccos(np.clip(dot, -1, 1)))


def test_a_real_camera_drives_an_avatars_fingers_and_expressions(data_dir, tmp_path):
    # the standing woman from the knees up (both hands and her face large enough for the page's whole-frame
    # hand and face search) as the camera; an avatar with four-joint fingers and ARKit-named morph targets
    # (none of the shared avatars has both)
    assert (ROOT / "src" / "kinetre" / "studio" / "static" / "index.html").is_file(), "run `make web` first"
    woman = Image.open(data_dir / "images" / "pose" / "standing_woman.png").convert("RGB")
    woman.crop((0, 0, woman.width, woman.height * 3 // 4)).save(tmp_path / "woman.png")
    video = y4m(tmp_path / "woman.png", tmp_path / "woman.y4m", seconds=1)
    write_rigged_avatar(tmp_path / "hands_face.glb")
    proc, url = start_server(sample_motion=False)
    try:
        r = run_driver("driver_hands.mjs", {"url": url + "/", "query": "?noshadows&nohands&noface&notiles",
                                            "video": str(video), "avatar": str(tmp_path / "hands_face.glb"),
                                            "out": str(HERE / "artifacts" / "hands-face.json")}, 600)
    finally:
        proc.terminate()
        proc.wait(60)
    assert r["seen"]["hands"] >= 6 and r["seenBodyOnly"]["hands"] == 0 and r["seenBodyOnly"]["faces"] == 0
    names = sorted(r["bodyOnly"][0]["fingerBones"])
    assert len(names) == 30  # ten fingers of four joints, three bones, found by name below the elbows
    rest, still = (np.array([a["fingerBones"][n] for n in names]) for a in r["bodyOnly"])
    driven = np.array([r["withHandsAndFace"]["fingerBones"][n] for n in names])
    # the body alone leaves the fingers where they are; the hands seen turn them
    assert quaternion_degrees(rest, still).max() < 0.01
    turned = quaternion_degrees(still, driven)
    turns = {n: round(float(d), 1) for n, d in zip(names, turned)}
    for side in ("Left", "Right"):
        hand = [d for n, d in turns.items() if side in n]
        assert np.median(hand) > 8, turns                   # most bones of each hand turn
        for finger in ("Thumb", "Index", "Middle", "Ring", "Pinky"):
            assert max(d for n, d in turns.items() if side in n and finger in n) > 5, turns  # every finger
    before, after = r["bodyOnly"][1]["morphs"], r["withHandsAndFace"]["morphs"]
    assert set(before) == set(MORPHS) and all(w == 0 for w in before.values())
    assert sum(w > 0.01 for w in after.values()) >= 1, after  # the face's blendshapes weigh the morphs
