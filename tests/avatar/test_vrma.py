"""VRM Animation out: `kinetre avatar … -o take.vrma` is validator-clean glTF that three-vrm's own loader
(VRMAnimationLoaderPlugin + createVRMAnimationClip, tests/export/node) plays on a VRM humanoid of other
proportions, which then points its limbs where the tracked ones point; face weights become VRM expressions."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from export.takes import validate_gltf
from kinetre.avatar.expressions import VRM_PRESETS, vrm_expressions
from kinetre.avatar.normalized import normalized_motion, vrm_name
from kinetre.avatar.retarget import retarget
from kinetre.avatar.vrma import write_vrma
from kinetre.cli import main
from kinetre.errors import ExportError

NODE = Path(__file__).resolve().parents[1] / "export" / "node"
# Kinect-20 bone (from, to) each normalised bone follows
FOLLOWS = {"leftUpperArm": ("ShoulderLeft", "ElbowLeft"), "leftLowerArm": ("ElbowLeft", "WristLeft"),
           "rightUpperArm": ("ShoulderRight", "ElbowRight"), "rightLowerArm": ("ElbowRight", "WristRight"),
           "leftUpperLeg": ("HipLeft", "KneeLeft"), "leftLowerLeg": ("KneeLeft", "AnkleLeft"),
           "rightUpperLeg": ("HipRight", "KneeRight"), "rightLowerLeg": ("KneeRight", "AnkleRight")}


def play(path, times):
    if not (NODE / "node_modules" / "@pixiv" / "three-vrm-animation").is_dir():
        raise RuntimeError(f"three-vrm is not installed: run `npm ci` in {NODE} (make setup does)")
    out = subprocess.run(["node", str(NODE / "vrma_three.mjs"), str(path), *map(str, times)], capture_output=True,
                         text=True, timeout=300, check=True)
    return json.loads(out.stdout)


def angle(a, b):
    a, b = np.asarray(a) / np.linalg.norm(a), np.asarray(b) / np.linalg.norm(b)
    return float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))


@pytest.mark.parametrize("name", ["RiggedFigure", "CesiumMan"])
def test_three_vrm_plays_the_cli_take_with_the_tracked_limb_directions(tmp_path, capsys, data_dir, rigged, walk,
                                                                      name):
    out = tmp_path / "take.vrma"
    assert main(["avatar", str(data_dir / "avatars" / f"{name}.glb"), "--motion",
                 str(data_dir / "bvh" / "cmu_12_01_walk.bvh"), "--max-frames", "24", "-o", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    report = validate_gltf(out)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    assert report["info"]["animationCount"] == 1

    avatar, bonemap, plan = rigged[name]
    norm = normalized_motion(plan, bonemap, retarget(plan, walk.positions[:24], walk.tracked[:24]))
    samples = [0, 7, 23]
    got = play(out, [k / 30 for k in samples])
    assert got["frames"] == 24 and abs(got["duration"] - 23 / 30) < 1e-6
    assert got["bones"] == [vrm_name(b) for b in norm.bones] and got["translated"] == ["hips"]
    assert {"hips", "spine", "head", "leftUpperArm", "leftLowerArm", "rightUpperLeg", "rightLowerLeg"} <= set(got["bones"])
    assert got["presets"] == [] and got["custom"] == []
    joints = walk.model.joints
    checked = 0
    for pose, k in zip(got["poses"], samples):
        # the receiver's hips follow, scaled by its hip height over the file's (1.3)
        assert np.allclose(pose["hips"], 1.3 * norm.hips[k], atol=1e-4 * norm.rest[0, 1])
        for bone, (a, b) in FOLLOWS.items():
            if bone not in pose["directions"] or plan.aim_from[bonemap.joints[_kinect(bone)]] < 0:
                continue
            tracked = walk.positions[k, joints.index(b)] - walk.positions[k, joints.index(a)]
            assert angle(pose["directions"][bone], tracked) < 2.0, (bone, k)
            checked += 1
    assert checked >= 12


def _kinect(bone):
    from kinetre.avatar.normalized import BONES
    return BONES[bone[0].upper() + bone[1:]][0]


def test_face_weights_become_vrm_presets_and_custom_expressions(tmp_path, rigged, walk):
    avatar, bonemap, plan = rigged["RiggedFigure"]
    t = 12
    names = ("_neutral", "jawOpen", "eyeBlinkLeft", "eyeBlinkRight", "mouthSmileLeft", "mouthSmileRight",
             "eyeLookOutLeft", "eyeLookInRight", "noseSneerLeft", "cheekPuff")
    ramp = np.linspace(0.0, 1.0, t)
    weights = np.stack([np.zeros(t), ramp, 0.8 * ramp, 0.5 * ramp, ramp, 0.5 * ramp, 0.6 * ramp, 0.2 * ramp,
                        1 - ramp, np.full(t, 0.25)], axis=1)
    preset, custom = vrm_expressions(names, weights)
    assert np.allclose(preset["aa"], ramp) and np.allclose(preset["happy"], 0.75 * ramp)
    assert np.allclose(preset["blink"], 0.5 * ramp) and np.allclose(preset["blinkLeft"], 0.3 * ramp)
    assert np.allclose(preset["blinkRight"], 0.0) and np.allclose(preset["lookLeft"], 0.4 * ramp)
    assert set(preset) == {"aa", "happy", "blink", "blinkLeft", "blinkRight", "lookLeft"}
    assert set(custom) == {"noseSneerLeft", "cheekPuff"}

    norm = normalized_motion(plan, bonemap, retarget(plan, walk.positions[:t], walk.tracked[:t]))
    out = tmp_path / "face.vrma"
    write_vrma(out, norm, 30.0, (preset, custom))
    report = validate_gltf(out)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    got = play(out, [0.0, 5 / 30, 0.5 / 30, 11 / 30])
    assert set(got["presets"]) == set(preset) and set(got["custom"]) == set(custom)
    for pose, frame in zip(got["poses"], [0.0, 5.0, 0.5, 11.0]):
        for label, w in {**preset, **custom}.items():
            expected = np.interp(frame, np.arange(t), w)          # linear keys, sampled between frames too
            assert abs(pose["weights"][label] - expected) < 1e-5, (label, frame)


def test_frames_without_a_face_hold_the_last_weights():
    faces = np.array([[0.1, 0.4], [np.nan, np.nan], [0.3, 0.2]])
    preset, custom = vrm_expressions(("jawOpen", "cheekPuff"), np.vstack([[np.nan, np.nan], faces]))
    assert np.allclose(preset["aa"], [0.0, 0.1, 0.1, 0.3]) and np.allclose(custom["cheekPuff"], [0, 0.4, 0.4, 0.2])


def test_every_preset_is_a_vrm_1_preset_name():
    vrm_presets = {"happy", "angry", "sad", "relaxed", "surprised", "aa", "ih", "ou", "ee", "oh", "blink",
                   "blinkLeft", "blinkRight", "lookUp", "lookDown", "lookLeft", "lookRight", "neutral"}
    assert set(VRM_PRESETS) <= vrm_presets


def test_bad_targets_are_named(tmp_path, rigged, walk):
    avatar, bonemap, plan = rigged["RiggedFigure"]
    norm = normalized_motion(plan, bonemap, retarget(plan, walk.positions[:3], walk.tracked[:3]))
    with pytest.raises(ExportError, match="must end in .vrma"):
        write_vrma(tmp_path / "x.glb", norm, 30.0)
    with pytest.raises(ExportError, match="'aa' needs 3 finite weights"):
        write_vrma(tmp_path / "x.vrma", norm, 30.0, ({"aa": np.array([0.0, np.nan, 1.0])}, {}))


def test_a_take_with_a_face_writes_vrm_expressions_through_the_cli(tmp_path, capsys, data_dir, walk):
    from kinetre.motion.stream import write_stream
    from kinetre.motion.take import Take
    t = 12
    names = ("_neutral", "jawOpen", "mouthSmileLeft", "mouthSmileRight", "cheekPuff")
    faces = np.stack([np.zeros(t), np.linspace(0, 1, t), np.full(t, 0.2), np.full(t, 0.6), np.full(t, 0.3)], 1)
    faces[4] = np.nan                                                # a frame where the face is lost
    take = Take(walk.model, walk.positions[:t], walk.tracked[:t], 30.0, "face", people=(0,),
                crowd_positions=walk.positions[:t, None], crowd_tracked=walk.tracked[:t, None],
                blendshapes=faces[:, None], blendshape_names=names)
    path = tmp_path / "face.kinetre.jsonl"
    write_stream(path, take)
    out = tmp_path / "face.vrma"
    assert main(["avatar", str(data_dir / "avatars" / "RiggedFigure.glb"), "--motion", str(path), "-o", str(out)]) == 0
    assert "VRM expressions: 2 presets, 1 custom" in capsys.readouterr().out
    got = play(out, [k / 30 for k in range(t)])
    assert got["frames"] == t and set(got["presets"]) == {"aa", "happy"} and got["custom"] == ["cheekPuff"]
    aa = [p["weights"]["aa"] for p in got["poses"]]
    expected = np.linspace(0, 1, t)
    expected[4] = expected[3]                                        # held through the lost frame
    assert np.allclose(aa, expected, atol=1e-5)
    assert np.allclose([p["weights"]["happy"] for p in got["poses"]], 0.4, atol=1e-5)


def bone_directions(path):
    """(T, B, 3) unit directions of every bone of a VRM Animation's humanoid, read by Kinetre's glTF reader,
    and the bones' child names."""
    from kinetre.motion.gltf import load_gltf
    take = load_gltf(path, as_kinect=False)
    bones = take.model.bones
    d = take.positions[:, bones[:, 1]] - take.positions[:, bones[:, 0]]
    return d / np.linalg.norm(d, axis=2, keepdims=True), [take.model.joints[c] for c in bones[:, 1]]


def test_a_vrma_kinetre_wrote_drives_an_avatar_again(tmp_path, data_dir, capsys):
    """.vrma in: the take Kinetre wrote is a --motion source; driving the same avatar with it writes the
    same limb directions again."""
    from kinetre.motion.source import load_take
    first, second = tmp_path / "first.vrma", tmp_path / "second.vrma"
    avatar = str(data_dir / "avatars" / "CesiumMan.glb")
    assert main(["avatar", avatar, "--motion", str(data_dir / "bvh" / "cmu_12_01_walk.bvh"), "--max-frames", "16",
                 "-o", str(first), "-q"]) == 0
    take = load_take(first)
    assert take.model.name == "kinect20" and len(take) == 16 and take.tracked.all()
    assert main(["avatar", avatar, "--motion", str(first), "-o", str(second), "-q"]) == 0
    a, names = bone_directions(first)
    b, _ = bone_directions(second)
    err = np.degrees(np.arccos(np.clip((a * b).sum(axis=2), -1.0, 1.0)))
    # the hips' own bones (spine, upper legs) included: the hips turn as the file wrote them
    assert {"spine", "leftUpperLeg", "rightUpperLeg", "leftLowerArm", "rightLowerLeg"} <= set(names)
    assert err.max() < 1.0, dict(zip(names, err.max(axis=0).round(2)))
    assert np.allclose(load_take(first).hips_turns, load_take(second).hips_turns, atol=np.radians(1.0))


def test_a_vrma_three_js_wrote_drives_an_avatar_as_kinetres_own_does(tmp_path, data_dir):
    """.vrma from another tool: three-vrm's loader plays Kinetre's take on a humanoid of other proportions and
    node names, three.js's GLTFExporter writes that as a new .vrma (tests/export/node/vrma_rewrite_three.mjs),
    and driving the avatar with it points every limb where Kinetre's own file does, within 1°."""
    from kinetre.motion.source import load_take
    first, theirs, second = tmp_path / "first.vrma", tmp_path / "three.vrma", tmp_path / "second.vrma"
    avatar = str(data_dir / "avatars" / "CesiumMan.glb")
    assert main(["avatar", avatar, "--motion", str(data_dir / "bvh" / "cmu_12_01_walk.bvh"), "--max-frames", "16",
                 "-o", str(first), "-q"]) == 0
    if not (NODE / "node_modules" / "@pixiv" / "three-vrm-animation").is_dir():
        raise RuntimeError(f"three-vrm is not installed: run `npm ci` in {NODE} (make setup does)")
    subprocess.run(["node", str(NODE / "vrma_rewrite_three.mjs"), str(first), str(theirs)], capture_output=True,
                   text=True, timeout=300, check=True)
    assert validate_gltf(theirs)["issues"]["numErrors"] == 0
    take = load_take(theirs)
    assert take.model.name == "kinect20" and len(take) == 16 and take.tracked.all()
    assert main(["avatar", avatar, "--motion", str(theirs), "-o", str(second), "-q"]) == 0
    a, names = bone_directions(first)
    b, _ = bone_directions(second)
    assert np.degrees(np.arccos(np.clip((a[0] * a[-1]).sum(axis=1), -1.0, 1.0))).max() > 10.0  # the limbs move
    err = np.degrees(np.arccos(np.clip((a * b).sum(axis=2), -1.0, 1.0)))
    assert err.max() < 1.0, dict(zip(names, err.max(axis=0).round(2)))
