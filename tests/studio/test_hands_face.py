"""Hands and face blendshapes from a capture page: the skeleton message's fields, checked by the server, kept
per user, recorded into the take's stream as `kinetre capture` writes them, driving an avatar's fingers and
morph targets through `kinetre avatar`, sent on by `--vmc` (finger bones, Blend/Val) to a UDP receiver, and
a VMC performer's Blend/Val arriving as blendshapes (`--vmc-listen`)."""
from __future__ import annotations

import asyncio
import json
import socket
import subprocess
from pathlib import Path

import httpx
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from export.gltf_player import GltfPlayer
from kinetre.avatar.bonemap import map_bones
from kinetre.avatar.expressions import blendshapes_from_clips, map_expressions
from kinetre.avatar.load import load_avatar
from kinetre.avatar.normalized import FINGER_BONES, PARENTS, finger_bone
from kinetre.avatar.retarget import plan_retarget, retarget
from kinetre.cli import main
from kinetre.motion.capture import photo_people
from kinetre.motion.stream import read_stream
from kinetre.skeleton.mediapipe import BLENDSHAPES, FINGERS
from kinetre.skeleton.models import KINECT20
from kinetre.studio.channels import Hub
from kinetre.studio.protocol import ProtocolError, parse_frame, parse_message, skeleton_json
from kinetre.studio.subjects import SKELETONS
from kinetre.studio.vmc_in import VmcUsers
from kinetre.vmc.send import MIRROR, blend_frames, frame_bundle, vmc_frames
from studio.conftest import start_server
from studio.studio_ws import frame_message, possessed_client
from studio.vmc_receiver import vmc_receiver

from avatar.synthetic import MORPHS, write_rigged_avatar
from web_bundle import esbuild

WRISTS = [KINECT20.index("WristLeft"), KINECT20.index("WristRight")]
JAW = BLENDSHAPES.index("jawOpen")
NODE = Path(__file__).resolve().parent / "node"


@pytest.fixture(scope="module")
def avatar_file(tmp_path_factory):
    """The small rigged humanoid with Mixamo finger chains and ARKit-named morph targets."""
    path = tmp_path_factory.mktemp("avatar") / "hands_face.glb"
    write_rigged_avatar(path)
    return path


@pytest.fixture(scope="module")
def vmc_studio():
    """(URL, bundles) of a studio whose avatars send VMC to a UDP receiver on loopback (every bundle decoded)."""
    with vmc_receiver() as (port, bundles):
        proc, url = start_server(nodes=64, timeout=600, vmc=("127.0.0.1", port))
        yield url, bundles
        proc.terminate()
        proc.wait(10)


@pytest.fixture(scope="module")
def hand_shape(data_dir):
    """(2, 21, 3) the standing woman's hands, each relative to its wrist (MediaPipe on a real photo)."""
    person = photo_people(data_dir / "images" / "pose" / "standing_woman.png")[0]
    assert np.isfinite(person.hands).all()
    return person.hands - person.hands[:, :1]


def sent_frames(walk, hand_shape, count):
    """Per frame i: (skeleton, hands at its wrists, blendshapes): the left hand lost every 5th frame, the face
    every 7th; jawOpen opens and closes."""
    out = []
    for i in range(count):
        sk = walk[i]
        hands = hand_shape + sk.positions[WRISTS][:, None]
        if i % 5 == 4:
            hands[0] = np.nan
        face = None
        if i % 7 != 6:
            face = np.round(np.linspace(0.0, 0.5, len(BLENDSHAPES)) * (i % 3) / 2, 4)
            face[JAW] = round(0.5 + 0.45 * np.sin(i / 3), 4)
        out.append((sk, hands, face))
    return out


def test_hands_and_blendshapes_survive_the_message_both_ways(walk, hand_shape):
    sk, hands, face = sent_frames(walk, hand_shape, 5)[4]
    frame = parse_frame(json.loads(skeleton_json("c1", 7, 12.5, sk, hands, face)))
    assert frame.seq == 7 and frame.t == 12.5
    assert np.isnan(frame.hands[0]).all()                      # the lost left hand: null on the wire
    np.testing.assert_array_equal(frame.hands[1], hands[1])
    np.testing.assert_array_equal(frame.blendshapes, face)
    plain = parse_frame(json.loads(skeleton_json("c1", 8, 13.0, sk)))
    assert plain.hands is None and plain.blendshapes is None


@pytest.mark.parametrize("fields, reason", [
    ({"hands": [None]}, "'hands' must be [left, right]"),
    ({"hands": [None, [[0.0, 1.0, 2.0]] * 20]}, "right hand must be 21"),
    ({"hands": [[[0.0, 1.0, True]] * 21, None]}, "left hand must be 21"),
    ({"hands": [[[0.0, 1.0, float("nan")]] * 21, None]}, "not finite"),
    ({"blendshapes": [0.1] * 51}, "must be 52 numbers"),
    ({"blendshapes": [0.1] * 25 + [float("nan")] + [0.1] * 26}, "'jawOpen' must be a weight in 0..1"),
    ({"blendshapes": [1.5] * 52}, "'_neutral' must be a weight in 0..1, got 1.5"),
])
def test_bad_hands_and_blendshapes_are_refused_by_name(walk, fields, reason):
    msg = {**json.loads(frame_message(1, walk[0])), **fields}
    with pytest.raises(ProtocolError, match=reason.replace("[", r"\[").replace("]", r"\]")):
        parse_frame(msg)


def test_a_studio_take_records_the_hands_and_face_sent_and_drives_an_avatar(vmc_studio, walk, hand_shape,
                                                                           avatar_file, tmp_path, capsys):
    studio, bundles = vmc_studio
    frames = sent_frames(walk, hand_shape, 40)
    r = httpx.post(f"{studio}/api/avatar", params={"name": "hands_face.glb"}, content=avatar_file.read_bytes(),
                   timeout=60)
    assert r.status_code == 200

    async def go():
        c = await possessed_client(studio, walk)
        try:
            async with httpx.AsyncClient(base_url=studio, timeout=120) as http:
                await http.post("/api/record/start")
                for i, (sk, hands, face) in enumerate(frames[1:], 1):
                    solved = c.transform_count
                    await c.send(frame_message(i + 1, sk, hands=hands, blendshapes=face))
                    await asyncio.sleep(1 / 30)
                    await c.wait(lambda c: c.transform_count > solved, 30)   # each frame solved, so recorded
                bad = json.loads(frame_message(len(frames) + 1, walk[0], blendshapes=np.zeros(52)))
                bad["blendshapes"][JAW] = float("nan")   # json.dumps writes NaN, which JSON parsers accept
                await c.send(json.dumps(bad))
                await c.wait(lambda c: any(m["type"] == "error" for m in c.messages))
                stats = await c.stats()
                await asyncio.sleep(0.5)
                take = (await http.post("/api/record/stop")).json()
                stream = (await http.get(take["meshes"][0]["files"]["stream"])).text
            return stats, [m for m in c.messages if m["type"] == "error"], stream
        finally:
            await c.__aexit__(None, None, None)

    stats, errors, stream = asyncio.run(go())
    assert stats["malformed"] == 1 and "'jawOpen' must be a weight" in errors[0]["message"]
    path = tmp_path / "studio_take.kinetre.jsonl"
    path.write_text(stream)
    take = read_stream(path)
    assert take.people == (0,) and take.blendshape_names == BLENDSHAPES and len(take) >= 20
    hands, faces = take.main_hands(), take.main_blendshapes()
    matched = set()
    # the body was cleaned before the solve (the header says so, so nothing cleans the take again): each
    # take frame is found by its right hand, which is sent whole every frame and recorded as sent
    assert take.applied["smoothing"]["pass"] == "causal" and "contact" in take.applied
    for k in range(len(take)):
        i = next(i for i, (_, hands_sent, _) in enumerate(frames) if np.array_equal(hands_sent[1], hands[k][1]))
        matched.add(i)
        upper = [j for j, name in enumerate(KINECT20.joints) if not name.startswith(("Hip", "Knee", "Ankle", "Foot"))]
        assert np.abs(frames[i][0].positions[upper] - take.positions[k, upper]).max() < 0.05  # smoothed, not moved
        np.testing.assert_array_equal(hands[k], frames[i][1])            # bit for bit, NaN where not seen
        np.testing.assert_array_equal(faces[k], np.full(52, np.nan) if frames[i][2] is None else frames[i][2])
    assert len(matched) >= 30

    glb = tmp_path / "studio_avatar.glb"
    assert main(["avatar", str(avatar_file), "--motion", str(path), "-o", str(glb)]) == 0
    said = capsys.readouterr().out
    assert "finger chains follow the hands" in said and f"drive {len(MORPHS)} morph targets" in said
    player = GltfPlayer(glb)
    body = [n.name for n in player.doc.nodes].index("body")
    held = faces.copy()
    for k in range(1, len(held)):                       # a frame without a face keeps the last weights
        if np.isnan(held[k]).all():
            held[k] = held[k - 1]
    for k in range(len(take)):
        want = np.nan_to_num(held[k, [BLENDSHAPES.index(m) for m in MORPHS]])
        np.testing.assert_allclose(player.morph_weights(k / take.fps, player.tracks)[body], want, atol=1e-5)
    assert np.ptp(held[:, JAW]) > 0.3                    # the jaw moved: a weight that shows

    check_vmc_out(bundles, frames)


def check_vmc_out(bundles, frames):
    """The studio's VMC bundles while the frames came: each face as VRM presets and ARKit names with the values
    sent, and the finger bones of each hand in view along its landmark segments."""
    arkit = [n for n in BLENDSHAPES if not n.startswith("_")]
    faced = [(i, face) for i, (_, _, face) in enumerate(frames) if face is not None]
    matched = 0
    for messages in bundles:
        blend = {p[0]: p[1] for a, p in messages if a == "/VMC/Ext/Blend/Val"}
        if not blend:
            continue
        assert [a for a, _ in messages][-1] == "/VMC/Ext/Blend/Apply"
        got = np.array([blend[n] for n in arkit])
        i, face = next(((i, f) for i, f in faced if np.abs(got - f[1:]).max() < 1e-6), (None, None))
        assert i is not None, "a Blend/Val set that matches no face sent"
        matched += 1
        assert abs(blend["A"] - face[JAW]) < 1e-6
        left, right = (face[BLENDSHAPES.index(n)] for n in ("eyeBlinkLeft", "eyeBlinkRight"))
        both = min(left, right)
        assert abs(blend["Blink"] - both) < 1e-6 and abs(blend["Blink_L"] - (left - both)) < 1e-6
        local = {p[0]: Rotation.from_quat(p[4:8]).as_matrix() for a, p in messages if a == "/VMC/Ext/Bone/Pos"}
        hands = frames[i][1]
        for side in (0, 1):
            sent = {finger_bone(side, f, k) in local for f in FINGERS for k in range(3)}
            assert sent == {bool(np.isfinite(hands[side]).all())}    # a hand out of view: no finger bones
        world = {}
        for name in local:                                       # parents come first
            parent = PARENTS[name]
            world[name] = local[name] if parent is None else world[parent] @ local[name]
        for finger, marks in FINGERS.items():
            for k in range(3):
                b = finger_bone(1, finger, k)
                seg = hands[1, marks[k + 1]] - hands[1, marks[k]]
                along = MIRROR @ world[b] @ MIRROR @ np.array(FINGER_BONES[b][1])   # back in Kinetre's axes
                angle = np.degrees(np.arccos(np.clip(along @ seg / np.linalg.norm(seg), -1, 1)))
                assert angle < 0.5, f"{b}: {angle:.2f} degrees off its hand segment"
    assert matched >= 10


def test_a_vmc_performers_blend_values_become_blendshapes_that_drive_expressions(avatar_file, walk):
    """`--vmc-listen`: Blend/Val clips (VRM 0.x presets and ARKit names) after a performer's bones become the
    user's blendshapes on the bus and in the skeleton message pages get, and weigh an avatar's morph targets."""
    avatar = load_avatar(avatar_file)
    bonemap = map_bones(avatar)
    plan = plan_retarget(avatar, bonemap)
    vmc = vmc_frames(plan, bonemap, retarget(plan, np.stack([w.positions for w in walk[:3]]),
                                             np.stack([w.tracked for w in walk[:3]])))
    clips = [{"A": 0.6, "Blink_L": 0.3, "Joy": 0.5}, {"eyeWideLeft": 0.8, "A": 0.2}, {"JawOpen": 0.9}]

    async def go():
        hub = Hub()
        sub = hub.subscribe(SKELETONS)

        async def command(client, msg):
            return None
        users = VmcUsers(hub, command, port=0)
        await users.start()
        out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        got = []
        for k, blend in enumerate(clips):
            out.sendto(frame_bundle(vmc, k, k / 30, blend), ("127.0.0.1", users.port))
            got.append(await sub.next(5))
        out.close()
        users.close()
        return got

    got = asyncio.run(go())
    face = [g.value.blendshapes for g in got]
    at = {n: i for i, n in enumerate(BLENDSHAPES)}
    assert face[0][at["jawOpen"]] == pytest.approx(0.6) and face[0][at["eyeBlinkLeft"]] == pytest.approx(0.3)
    assert face[0][at["mouthSmileLeft"]] == pytest.approx(0.5) and face[0][at["eyeBlinkRight"]] == 0.0
    # a clip keeps its weight until sent again: Blink_L and Joy still hold in the second frame
    assert face[1][at["jawOpen"]] == pytest.approx(0.2) and face[1][at["eyeWideLeft"]] == pytest.approx(0.8)
    assert face[1][at["eyeBlinkLeft"]] == pytest.approx(0.3)
    assert face[2][at["jawOpen"]] == pytest.approx(0.9)                   # the ARKit name beats the preset A
    for g in got:                                                         # pages get the same in the JSON
        np.testing.assert_array_equal(parse_frame(parse_message(g.data)).blendshapes, g.value.blendshapes)
    weights = map_expressions(avatar, BLENDSHAPES).weights(np.stack(face))[0]
    np.testing.assert_allclose(weights[:, [MORPHS.index("jawOpen"), MORPHS.index("eyeBlinkLeft")]],
                               [[0.6, 0.3], [0.2, 0.3], [0.9, 0.3]], atol=1e-6)


def test_the_senders_clips_read_back_as_the_face_sent():
    """Kinetre's own Blend/Val set (presets and ARKit names) read by its receiver gives the 51 weights back."""
    face = np.random.default_rng(3).uniform(0, 1, (1, len(BLENDSHAPES)))
    back = blendshapes_from_clips(blend_frames(BLENDSHAPES, face)[0], BLENDSHAPES)
    np.testing.assert_allclose(back[1:], face[0, 1:], atol=1e-12)
    assert blendshapes_from_clips({"Neutral": 1.0, "myCustomClip": 0.5}, BLENDSHAPES) is None


def test_an_avatar_take_from_the_page_exports_its_fingers_and_morph_weights(vmc_studio, walk, hand_shape,
                                                                            avatar_file, tmp_path):
    """POST /api/avatars/{id}/takes with the hands and blendshapes the page recorded: the GLB's morph weights
    are the faces sent (a frame without one holds the last), and a bad hand is refused naming its frame."""
    studio, _ = vmc_studio
    frames = sent_frames(walk, hand_shape, 8)
    avatar = httpx.post(f"{studio}/api/avatar", params={"name": "hands_face.glb"},
                        content=avatar_file.read_bytes(), timeout=60).json()["id"]
    rows = [json.loads(frame_message(i, sk, hands=h, blendshapes=f)) for i, (sk, h, f) in enumerate(frames)]
    body = {"fps": 10, "positions": [r["positions"] for r in rows], "tracked": [r["tracked"] for r in rows],
            "hands": [r.get("hands") for r in rows], "blendshapes": [r.get("blendshapes") for r in rows]}
    r = httpx.post(f"{studio}/api/avatars/{avatar}/takes", json=body, timeout=120)
    assert r.status_code == 200, r.text
    glb = tmp_path / "avatar_take.glb"
    glb.write_bytes(httpx.get(studio + r.json()["files"]["glb"], timeout=60).content)
    player = GltfPlayer(glb)
    mesh = [n.name for n in player.doc.nodes].index("body")
    last = None
    for k, (_, _, face) in enumerate(frames):
        last = face if face is not None else last
        want = last[[BLENDSHAPES.index(m) for m in MORPHS]]
        np.testing.assert_allclose(player.morph_weights(k / 10, player.tracks)[mesh], want, atol=1e-5)
    assert any(c.target.path == "rotation" and "Index" in player.doc.nodes[c.target.node].name
               for c in player.doc.animations[0].channels)
    body["hands"][3] = [[[0.0, 1.0]] * 21, None]
    bad = httpx.post(f"{studio}/api/avatars/{avatar}/takes", json=body, timeout=60)
    assert bad.status_code == 400 and bad.json()["error"].startswith("frame 3: the left hand must be 21")


def test_the_pages_hand_and_face_fields_are_what_the_server_reads(tmp_path, walk, hand_shape):
    """The page's handsFaceFields (web/src/net/handsFace.ts, run under node) on MediaPipe-like input: the
    server parses its fields to the hands at 0.1 mm and the scores, by name, at 1e-4; a face lacking a name
    and a frame without hands send neither field."""
    bundle = tmp_path / "handsFace.js"
    esbuild(["net/handsFace.ts"], f"--outfile={bundle}")
    sk, hands, _ = sent_frames(walk, hand_shape, 5)[4]                 # the left hand lost
    rng = np.random.default_rng(5)
    scores = {n: float(w) for n, w in zip(BLENDSHAPES[::-1], rng.uniform(0, 1, len(BLENDSHAPES)))}  # any order
    cases = [{"hands": [None, hands[1].tolist()], "scores": scores},
             {"hands": [None, None], "scores": {n: w for n, w in scores.items() if n != "jawOpen"}}]
    run = subprocess.run(["node", str(NODE / "hands_face_wire_ts.mjs"), str(bundle)], input=json.dumps(cases),
                         capture_output=True, text=True, timeout=120, check=True)
    full, partial = json.loads(run.stdout)
    frame = parse_frame({**json.loads(frame_message(1, sk)), **full["fields"]})
    assert np.isnan(frame.hands[0]).all()
    assert np.abs(frame.hands[1] - hands[1]).max() <= 0.5e-4 + 1e-12
    np.testing.assert_allclose(frame.blendshapes, [scores[n] for n in BLENDSHAPES], atol=0.5e-4 + 1e-12)
    assert full["back"] == dict(zip(BLENDSHAPES, frame.blendshapes.tolist()))
    assert partial == {"fields": {}, "back": None}
