"""Hands on an avatar's finger bones and face blendshapes on its morph targets: the finger map, the
per-segment retarget, the expression routes (ARKit names, VRM 1.0, VRM 0.x), and capture -> take ->
`kinetre avatar` -> glTF read back by the independent player."""
from __future__ import annotations

import cv2
import numpy as np
import pygltflib as gl
import pytest

from export.gltf_player import GltfPlayer
from export.takes import validate_gltf
from kinetre.avatar.bonemap import map_bones
from kinetre.avatar.drive import hands_and_face
from kinetre.avatar.expressions import map_expressions
from kinetre.avatar.fingers import map_fingers
from kinetre.avatar.load import load_avatar
from kinetre.avatar.retarget import plan_retarget, retarget, retarget_fingers
from kinetre.cli import main
from kinetre.motion.capture import photo_people
from kinetre.motion.stream import read_stream
from kinetre.motion.take import Take
from kinetre.skeleton.mediapipe import BLENDSHAPES, FINGERS

from avatar.synthetic import MORPHS, write_rigged_avatar


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    path = tmp_path_factory.mktemp("synthetic") / "hands_face.glb"
    write_rigged_avatar(path)
    avatar = load_avatar(path)
    bonemap = map_bones(avatar)
    return path, avatar, bonemap, plan_retarget(avatar, bonemap)


@pytest.fixture(scope="module")
def woman(data_dir):
    """The standing woman's body and both hands, as a 4-frame take whose frame 2 has lost the hands."""
    person = photo_people(data_dir / "images" / "pose" / "standing_woman.png")[0]
    sk = person.skeleton
    hands = np.repeat(person.hands[None, None], 4, axis=0)
    hands[2] = np.nan
    pos, tracked = np.repeat(sk.positions[None], 4, axis=0), np.repeat(sk.tracked[None], 4, axis=0)
    return Take(sk.model, pos, tracked, 10.0, "woman", (0,), pos[:, None], tracked[:, None], hands)


def bone_angles(plan, fingers, motion, hands, avatar):
    """Degrees between each finger bone (joint -> next joint in its chain) and the hand segment it follows,
    per frame: {(side, finger, bone): (T,)}; and the same for the bind pose."""
    src = hands @ plan.align.T
    out, bind = {}, {}
    for (side, finger), chain in fingers.chains.items():
        marks = FINGERS[finger]
        bones = len(chain) - 1
        for b in range(bones):
            k = int(round(b * 2 / max(bones - 1, 1)))
            seg = src[:, side, marks[k + 1]] - src[:, side, marks[k]]
            d = motion.positions[:, chain[b + 1]] - motion.positions[:, chain[b]]
            rest = avatar.bind_positions[chain[b + 1]] - avatar.bind_positions[chain[b]]
            cos = np.einsum("ti,ti->t", d, seg) / np.linalg.norm(d, axis=1) / np.linalg.norm(seg, axis=1)
            out[side, finger, b] = np.degrees(np.arccos(np.clip(cos, -1, 1)))
            bind[side, finger, b] = np.degrees(np.arccos(np.clip(seg @ rest / np.linalg.norm(seg, axis=1)
                                                                 / np.linalg.norm(rest), -1, 1)))
    return out, bind


def test_finger_chains_are_found_by_name_on_a_real_and_a_synthetic_rig(rigged, synthetic):
    avatar, bonemap, _ = rigged["robot_quaternius"]
    chains = map_fingers(avatar, bonemap).chains
    names = {key: [avatar.joint_names[j] for j in chain] for key, chain in chains.items()}
    assert names[0, "index"] == ["Index.L", "Index2.L"] and names[1, "thumb"] == ["Thumb.R", "Thumb2.R"]
    assert set(names) == {(s, f) for s in (0, 1) for f in ("thumb", "index", "middle", "ring")}  # no little
    _, avatar, bonemap, _ = synthetic
    chains = map_fingers(avatar, bonemap).chains
    assert len(chains) == 10 and all(len(c) == 4 for c in chains.values())
    assert avatar.joint_names[chains[1, "little"][0]] == "mixamorig:RightHandPinky1"
    assert not map_fingers(*rigged["CesiumMan"][:2])                       # no finger joints at all


@pytest.mark.parametrize("which", ["robot_quaternius", "synthetic"])
def test_each_finger_bone_follows_its_hand_segment(rigged, synthetic, woman, which):
    avatar, bonemap, plan = rigged[which] if which in rigged else synthetic[1:]
    fingers = map_fingers(avatar, bonemap)
    body = retarget(plan, woman.positions, woman.tracked)
    motion = retarget_fingers(avatar, plan, fingers, body, woman.main_hands())
    angles, bind = bone_angles(plan, fingers, motion, woman.main_hands(), avatar)
    for key, a in angles.items():
        assert a[[0, 1, 3]].max() < 0.5, f"{which} {key}: {a.round(2)} degrees off"
        assert bind[key][0] > 10.0, f"{which} {key}: the hand pose is the bind pose ({bind[key][0]:.1f})"
    # the frame without hands keeps the last rotations; nothing moves but the fingers and what hangs on them
    np.testing.assert_allclose(motion.local[2], motion.local[1], atol=1e-12)
    finger_joints = {j for c in fingers.chains.values() for j in c}
    others = [j for j in range(len(avatar.joints)) if j not in finger_joints
              and not any(_below(plan.parents, j, f) for f in finger_joints)]
    np.testing.assert_allclose(motion.world[:, others], body.world[:, others], atol=1e-12)
    # bones keep their lengths
    p = motion.positions
    for chain in fingers.chains.values():
        for a, b in zip(chain, chain[1:]):
            np.testing.assert_allclose(np.linalg.norm(p[:, b] - p[:, a], axis=1),
                                       np.linalg.norm(avatar.bind_positions[b] - avatar.bind_positions[a]),
                                       rtol=1e-9)
    assert np.isfinite(motion.local).all()


def _below(parents, j, ancestor):
    while j >= 0:
        j = parents[j]
        if j == ancestor:
            return True
    return False


def test_arkit_named_targets_take_their_blendshapes(synthetic):
    _, avatar, _, _ = synthetic
    emap = map_expressions(avatar, BLENDSHAPES)
    assert emap.how == "names"
    faces = np.zeros((3, len(BLENDSHAPES)))
    faces[:, BLENDSHAPES.index("jawOpen")] = [0.1, 0.7, 0.3]
    faces[:, BLENDSHAPES.index("mouthSmileRight")] = 0.4
    faces[:, BLENDSHAPES.index("mouthSmileLeft")] = 0.9        # a near name must not be taken
    faces[1] = np.nan                                          # no face: the last weights are kept
    w = emap.weights(faces)[0]
    np.testing.assert_allclose(w, [[0.1, 0.0, 0.4], [0.1, 0.0, 0.4], [0.3, 0.0, 0.4]])
    assert not map_expressions(avatar, ("_neutral", "cheekPuff"))  # nothing in common: nothing to drive


@pytest.mark.parametrize("version", ["1.0", "0.x"])
def test_vrm_expressions_drive_their_bound_targets(synthetic, tmp_path, version):
    path, *_ = synthetic
    doc = gl.GLTF2.load(str(path))
    body = next(i for i, n in enumerate(doc.nodes) if n.mesh is not None)
    if version == "1.0":
        doc.extensions = {"VRMC_vrm": {"specVersion": "1.0", "expressions": {
            "preset": {"aa": {"morphTargetBinds": [{"node": body, "index": 2, "weight": 1.0}]},
                       "blinkLeft": {"morphTargetBinds": [{"node": body, "index": 0, "weight": 0.5}]}},
            "custom": {"cheekPuff": {"morphTargetBinds": [{"node": body, "index": 1, "weight": 1.0}]}}}}}
    else:
        doc.extensions = {"VRM": {"blendShapeMaster": {"blendShapeGroups": [
            {"name": "A", "presetName": "a", "binds": [{"mesh": 0, "index": 2, "weight": 100}]},
            {"name": "Blink_L", "presetName": "blink_l", "binds": [{"mesh": 0, "index": 0, "weight": 50}]},
            {"name": "cheekPuff", "presetName": "unknown", "binds": [{"mesh": 0, "index": 1, "weight": 100}]}]}}}
    doc.extensionsUsed = list(doc.extensions)
    out = tmp_path / "expressions.glb"
    doc.save_binary(str(out))
    emap = map_expressions(load_avatar(out), BLENDSHAPES)
    assert emap.how == "vrm"
    faces = np.zeros((1, len(BLENDSHAPES)))
    faces[0, BLENDSHAPES.index("jawOpen")] = 0.8
    faces[0, BLENDSHAPES.index("eyeBlinkLeft")] = 0.6
    faces[0, BLENDSHAPES.index("cheekPuff")] = 0.25
    np.testing.assert_allclose(emap.weights(faces)[0], [[0.3, 0.25, 0.8]])


@pytest.mark.slow
def test_capture_to_take_to_avatar_carries_finger_rotations_and_morph_weights(tmp_path, data_dir, synthetic,
                                                                             capsys):
    avatar_path, avatar, bonemap, plan = synthetic
    photo = cv2.imread(str(data_dir / "images" / "face" / "face_business_person.png"))
    h, w = (s // 2 * 2 for s in photo.shape[:2])
    video = tmp_path / "person.mp4"
    out = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10, (w, h))
    for _ in range(3):
        out.write(np.ascontiguousarray(photo[:h, :w]))
    out.release()
    take_path, glb = tmp_path / "person.kinetre.jsonl", tmp_path / "person.glb"
    assert main(["capture", "--video", str(video), "-o", str(take_path), "-q"]) == 0
    take = read_stream(take_path)
    hands, faces = take.main_hands(), take.main_blendshapes()
    assert take.people == (0,) and take.blendshape_names == BLENDSHAPES
    assert np.isfinite(hands[:, 1]).all() and np.isfinite(faces).all()     # her right hand and her face
    assert main(["avatar", str(avatar_path), "--motion", str(take_path), "-o", str(glb)]) == 0
    said = capsys.readouterr().out
    assert "finger chains follow the hands" in said and "drive 3 morph targets" in said

    report = validate_gltf(glb)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    player = GltfPlayer(glb)
    names = [n.name for n in player.doc.nodes]
    body = names.index("body")
    src = hands @ plan.align.T
    for k in range(len(take)):
        t = k / take.fps
        world = player.world_matrices(t)
        for finger, marks in FINGERS.items():
            word = "Pinky" if finger == "little" else finger.title()
            for b in range(3):
                a, c = (names.index(f"mixamorig:RightHand{word}{i}") for i in (b + 1, b + 2))
                bone = world[c][:3, 3] - world[a][:3, 3]
                seg = src[k, 1, marks[b + 1]] - src[k, 1, marks[b]]
                angle = np.degrees(np.arccos(bone @ seg / np.linalg.norm(bone) / np.linalg.norm(seg)))
                assert angle < 0.5, f"frame {k} right {finger} bone {b}: {angle:.2f} degrees off its segment"
        want = faces[k, [BLENDSHAPES.index(m) for m in MORPHS]]
        np.testing.assert_allclose(player.morph_weights(t, player.tracks)[body], want, atol=1e-6)
    assert faces[:, BLENDSHAPES.index("mouthSmileRight")].min() > 0.1        # she smiles: a weight that shows
    motion, morphs = hands_and_face(avatar, bonemap, plan, retarget(plan, take.positions, take.tracked), take)
    assert set(morphs) == {0} and morphs[0].shape == (len(take), len(MORPHS))


def test_each_person_of_a_camera_take_drives_their_own_avatar(tmp_path, data_dir, walk, capsys):
    from kinetre.motion.stream import write_stream
    other = walk.transformed(rotation=np.diag([-1.0, 1.0, -1.0]), translation=(1.5, 0.0, 0.0))  # walks back
    crowd = np.stack([walk.positions, other.positions], axis=1)
    two = Take(walk.model, walk.positions, walk.tracked, walk.fps, "two", (0, 1), crowd,
               np.stack([walk.tracked, other.tracked], axis=1))
    write_stream(tmp_path / "two.kinetre.jsonl", two)
    write_stream(tmp_path / "second.kinetre.jsonl", other)
    avatar = data_dir / "avatars" / "RiggedFigure.glb"
    outs = {}
    # --raw: a take with people is a camera take, cleaned by default; this compares the people as they are
    for name, argv in (("person1", ["--motion", tmp_path / "two.kinetre.jsonl", "--person", 1, "--raw"]),
                       ("alone", ["--motion", tmp_path / "second.kinetre.jsonl", "--raw"])):
        outs[name] = tmp_path / f"{name}.bvh"
        assert main(["avatar", str(avatar), *map(str, argv), "-q", "-o", str(outs[name])]) == 0
    assert outs["person1"].read_text() == outs["alone"].read_text()
    main_person = tmp_path / "main.bvh"                    # without --person: the main person (id 0)
    assert main(["avatar", str(avatar), "--motion", str(tmp_path / "two.kinetre.jsonl"), "--raw", "-q", "-o",
                 str(main_person)]) == 0
    assert main_person.read_text() != outs["alone"].read_text()
    capsys.readouterr()
    assert main(["avatar", str(avatar), "--motion", str(tmp_path / "two.kinetre.jsonl"), "--person", "9",
                 "-o", str(tmp_path / "x.bvh")]) == 2
    assert "no person 9 (the take has [0, 1])" in capsys.readouterr().err

