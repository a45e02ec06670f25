"""The studio page drives an avatar's fingers and face in TypeScript (web/src/avatar/Fingers.ts,
Expressions.ts): on one fixture (a real walk, hands whose finger segments point anywhere, one hand lost
for a frame, faces with random blendshapes) it gives the Python retarget_fingers and map_expressions
numbers, each finger bone of the three.js skeleton follows its hand segment, and the morph weights land
in three.js's morphTargetInfluences."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pygltflib as gl
import pytest

from kinetre.avatar.bonemap import map_bones
from kinetre.avatar.expressions import map_expressions
from kinetre.avatar.fingers import map_fingers
from kinetre.avatar.load import load_avatar
from kinetre.avatar.retarget import plan_retarget, retarget, retarget_fingers
from kinetre.skeleton.mediapipe import BLENDSHAPES, FINGERS
from kinetre.skeleton.models import KINECT20

from avatar.synthetic import MORPHS, write_rigged_avatar
from web_bundle import esbuild

RUNNER = Path(__file__).resolve().parent / "node" / "hands_face_ts.mjs"
HANDS_RUNNER = Path(__file__).resolve().parent / "node" / "person_hands_ts.mjs"
FRAMES = 6


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    out = tmp_path_factory.mktemp("ts")
    esbuild(["avatar/retarget.ts", "avatar/Fingers.ts", "avatar/Expressions.ts", "capture/hands.ts"],
            f"--outdir={out}", "--entry-names=[name]")
    return out


def hands_at_wrists(walk, rng) -> np.ndarray:
    """(T, 2, 21, 3): each hand's landmark 0 at the walk's wrist, every finger segment 3 cm in a random
    direction (so no bone is near its bind direction); the left hand lost in frame 3, the right in 4."""
    hands = np.empty((FRAMES, 2, 21, 3))
    for t in range(FRAMES):
        for side, wrist in enumerate(("WristLeft", "WristRight")):
            hands[t, side, 0] = walk.positions[t, KINECT20.index(wrist)]
            for marks in FINGERS.values():
                prev = hands[t, side, 0]
                for m in marks:
                    d = rng.normal(size=3)
                    hands[t, side, m] = prev + 0.03 * d / np.linalg.norm(d)
                    prev = hands[t, side, m]
    hands[3, 0] = np.nan
    hands[4, 1] = np.nan
    return hands


def test_page_hands_and_face_match_python(bundle, tmp_path, walk):
    path = tmp_path / "hands_face.glb"
    write_rigged_avatar(path)
    avatar = load_avatar(path)
    bonemap = map_bones(avatar)
    plan = plan_retarget(avatar, bonemap)
    fingers = map_fingers(avatar, bonemap)
    rng = np.random.default_rng(3)
    pos, tracked = walk.positions[:FRAMES], walk.tracked[:FRAMES]
    hands = hands_at_wrists(walk, rng)
    faces = rng.random((FRAMES, len(BLENDSHAPES)))
    faces[2] = np.nan                                   # no face: the page keeps the last weights
    fixture = {
        "plan": plan.to_json(), "joints": list(avatar.joint_names), "nodes": [int(n) for n in avatar.joints],
        "map": {k: int(v) for k, v in bonemap.joints.items()}, "tracked": tracked.tolist(),
        "positions": [[p.tolist() if ok else None for p, ok in zip(f, t)] for f, t in zip(pos, tracked)],
        "hands": [[None if np.isnan(h).any() else h.tolist() for h in f] for f in hands],
        "faces": [None if np.isnan(f).any() else dict(zip(BLENDSHAPES, f.tolist())) for f in faces],
    }
    out = subprocess.run(["node", str(RUNNER), str(bundle), str(path)], input=json.dumps(fixture),
                         capture_output=True, text=True, timeout=120, check=True)
    page = json.loads(out.stdout)

    # the same chains and the same numbers as Python
    assert {(c["side"], c["finger"]): tuple(c["joints"]) for c in page["chains"]} == fingers.chains
    ours = retarget_fingers(avatar, plan, fingers, retarget(plan, pos, tracked), hands)
    size = np.ptp(avatar.bind_positions)
    np.testing.assert_allclose(np.array(page["world"]), ours.world, atol=1e-9 * size)
    np.testing.assert_allclose(np.array(page["local"]), ours.local, atol=1e-9 * size)

    # three.js's bones, posed by the page's local matrices: each finger bone along its hand segment
    bones = np.array(page["bones"])
    src = hands @ plan.align.T
    worst = 0.0
    for (side, finger), chain in fingers.chains.items():
        marks = FINGERS[finger]
        for b in range(len(chain) - 1):
            seg = src[:, side, marks[b + 1]] - src[:, side, marks[b]]
            d = bones[:, chain[b + 1]] - bones[:, chain[b]]
            seen = np.isfinite(seg).all(axis=1)
            cos = np.einsum("ti,ti->t", d[seen], seg[seen]) / np.linalg.norm(d[seen], axis=1) \
                / np.linalg.norm(seg[seen], axis=1)
            worst = max(worst, np.degrees(np.arccos(np.clip(cos, -1, 1))).max())
            # a lost hand keeps its fingers' local rotations
            lost = 3 if side == 0 else 4
            np.testing.assert_allclose(np.array(page["local"])[lost, chain[b], :3, :3],
                                       np.array(page["local"])[lost - 1, chain[b], :3, :3], atol=1e-12)
    assert worst < 1.0, f"a finger bone is {worst:.3f} degrees off its hand segment"
    assert not np.allclose(np.array(page["local"])[0, fingers.chains[0, "index"][0]][:3, :3], np.eye(3), atol=0.1)

    # morph weights, exactly as Python's map, in morphTargetInfluences (a frame without a face holds)
    assert page["how"] == "names"
    expected = map_expressions(avatar, BLENDSHAPES).weights(faces)[0]
    got = np.array([f["0"] for f in page["morphs"]])
    np.testing.assert_allclose(got, expected, atol=1e-12)
    jaw = faces[:, BLENDSHAPES.index("jawOpen")]
    np.testing.assert_allclose(got[[0, 1, 3], MORPHS.index("jawOpen")], jaw[[0, 1, 3]], atol=1e-12)


@pytest.mark.parametrize("version", ["1.0", "0.x"])
def test_page_vrm_expressions_match_python(bundle, tmp_path, walk, version):
    path = tmp_path / "plain.glb"
    write_rigged_avatar(path)
    doc = gl.GLTF2.load(str(path))
    body = next(i for i, n in enumerate(doc.nodes) if n.mesh is not None)
    if version == "1.0":
        doc.extensions = {"VRMC_vrm": {"specVersion": "1.0", "expressions": {
            "preset": {"aa": {"morphTargetBinds": [{"node": body, "index": 2, "weight": 1.0}]},
                       "happy": {"morphTargetBinds": [{"node": body, "index": 2, "weight": 0.5}]},
                       "blinkLeft": {"morphTargetBinds": [{"node": body, "index": 0, "weight": 0.5}]}},
            "custom": {"cheekPuff": {"morphTargetBinds": [{"node": body, "index": 1, "weight": 1.0}]}}}}}
    else:
        doc.extensions = {"VRM": {"blendShapeMaster": {"blendShapeGroups": [
            {"name": "A", "presetName": "a", "binds": [{"mesh": 0, "index": 2, "weight": 100}]},
            {"name": "Joy", "presetName": "joy", "binds": [{"mesh": 0, "index": 2, "weight": 50}]},
            {"name": "Blink", "presetName": "blink", "binds": [{"mesh": 0, "index": 0, "weight": 50}]},
            {"name": "cheekPuff", "presetName": "unknown", "binds": [{"mesh": 0, "index": 1, "weight": 100}]}]}}}
    out = tmp_path / "expressions.glb"
    doc.save_binary(str(out))
    avatar = load_avatar(out)
    bonemap = map_bones(avatar)
    faces = np.random.default_rng(5).random((2, len(BLENDSHAPES))) * 0.6
    fixture = {"plan": plan_retarget(avatar, bonemap).to_json(), "joints": list(avatar.joint_names),
               "nodes": [int(n) for n in avatar.joints], "map": {k: int(v) for k, v in bonemap.joints.items()},
               "tracked": walk.tracked[:2].tolist(), "positions": walk.positions[:2].tolist(),
               "hands": [[None, None]] * 2, "faces": [dict(zip(BLENDSHAPES, f.tolist())) for f in faces]}
    run = subprocess.run(["node", str(RUNNER), str(bundle), str(out)], input=json.dumps(fixture),
                         capture_output=True, text=True, timeout=120, check=True)
    page = json.loads(run.stdout)
    assert page["how"] == "vrm"
    expected = map_expressions(avatar, BLENDSHAPES).weights(faces)[0]
    np.testing.assert_allclose(np.array([f["0"] for f in page["morphs"]]), expected, atol=1e-12)
    smile = faces[:, [BLENDSHAPES.index("mouthSmileLeft"), BLENDSHAPES.index("mouthSmileRight")]].mean(axis=1)
    np.testing.assert_allclose(expected[:, 2], np.clip(faces[:, BLENDSHAPES.index("jawOpen")] + 0.5 * smile, 0, 1))


def test_page_gives_each_wrist_the_hand_that_starts_at_it(bundle):
    """Hands go to the wrist their landmark 0 is at, whatever MediaPipe's handedness says; a hand far from
    both wrists is nobody's; world landmarks are flipped to +Y up, +Z to the camera, at the body's wrist."""
    rng = np.random.default_rng(7)
    image = [{"x": 0.5, "y": 0.5, "z": 0.0, "visibility": 1.0} for _ in range(33)]
    image[15] = {"x": 0.3, "y": 0.6, "z": 0.0}                   # the person's left wrist
    image[16] = {"x": 0.7, "y": 0.6, "z": 0.0}
    positions = [[0.0, 1.0, 0.0]] * 20
    positions[KINECT20.index("WristLeft")] = [0.4, 1.1, 0.2]
    positions[KINECT20.index("WristRight")] = [-0.4, 1.1, 0.2]
    frame = {"positions": positions, "tracked": [True] * 20}

    def hand(x, y, label):
        world = rng.normal(scale=0.04, size=(21, 3))
        shape = rng.normal(scale=0.02, size=(21, 2)) + [0.0, -0.05]
        shape[0] = 0.0
        return {"handedness": label, "world": [dict(zip("xyz", p)) for p in world.tolist()],
                "image": [{"x": x + a, "y": y + b, "z": 0.0} for a, b in shape.tolist()]}, world
    right, right_world = hand(0.705, 0.59, "Left")
    left, left_world = hand(0.29, 0.61, "Left")
    far, _ = hand(0.5, 0.05, "Right")
    cases = [{"pose": {"image": image, "world": image}, "frame": frame, "hands": h, "aspect": 16 / 9}
             for h in ([far, right, left], [far])]
    run = subprocess.run(["node", str(HANDS_RUNNER), str(bundle)], input=json.dumps(cases), capture_output=True,
                         text=True, timeout=120, check=True)
    (got_left, got_right), alone = json.loads(run.stdout)
    flip = np.diag([1.0, -1.0, -1.0])
    for got, world, wrist in ((got_left, left_world, "WristLeft"), (got_right, right_world, "WristRight")):
        np.testing.assert_allclose(np.array(got), (world - world[0]) @ flip + positions[KINECT20.index(wrist)],
                                   atol=1e-12)
    assert alone == [None, None]
