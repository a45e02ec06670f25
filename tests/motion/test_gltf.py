"""glTF animations as takes: the sampler against a hand-made two-joint file with known keyframes, and Fox."""
from __future__ import annotations

import math
import struct

import numpy as np
import pygltflib as gl
import pytest

from kinetre.errors import BadMotionError
from kinetre.motion.gltf import animations, load_gltf, sample
from kinetre.rotation import slerp
from kinetre.motion.source import load_take


def _two_joints(path):
    """base (non-joint: at x=1, scaled 2) -> A (at y=1; rotation LINEAR 0 -> 90 deg about Z over 1 s;
    scale STEP 1 -> 3 at 0.5 s) -> B (translation CUBICSPLINE: (0,1,0) at both keys, tangents (1,0,0))."""
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    arrays = [
        (np.array([0.0, 1.0], np.float32), "SCALAR"),                                 # 0 rotation times
        (np.array([[0, 0, 0, 1], [0, 0, s, c]], np.float32), "VEC4"),                 # 1 rotations
        (np.array([0.0, 0.5], np.float32), "SCALAR"),                                 # 2 scale times
        (np.array([[1, 1, 1], [3, 3, 3]], np.float32), "VEC3"),                       # 3 scales
        (np.array([[9, 9, 9], [0, 1, 0], [1, 0, 0],                                   # 4 in, value, out
                   [1, 0, 0], [0, 1, 0], [9, 9, 9]], np.float32), "VEC3"),
    ]
    blob, views, accessors = b"", [], []
    for i, (a, kind) in enumerate(arrays):
        views.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=a.nbytes))
        accessors.append(gl.Accessor(bufferView=i, componentType=gl.FLOAT, count=len(a), type=kind,
                                     min=[float(a.min())] if kind == "SCALAR" else None,
                                     max=[float(a.max())] if kind == "SCALAR" else None))
        blob += a.tobytes()
    doc = gl.GLTF2(
        scene=0, scenes=[gl.Scene(nodes=[0])],
        nodes=[gl.Node(name="base", translation=[1, 0, 0], scale=[2, 2, 2], children=[1]),
               gl.Node(name="A", translation=[0, 1, 0], children=[2]),
               gl.Node(name="B", translation=[0, 1, 0])],
        skins=[gl.Skin(joints=[1, 2])],
        animations=[gl.Animation(name="bend", samplers=[
            gl.AnimationSampler(input=0, output=1, interpolation="LINEAR"),
            gl.AnimationSampler(input=2, output=3, interpolation="STEP"),
            gl.AnimationSampler(input=0, output=4, interpolation="CUBICSPLINE")], channels=[
            gl.AnimationChannel(sampler=0, target=gl.AnimationChannelTarget(node=1, path="rotation")),
            gl.AnimationChannel(sampler=1, target=gl.AnimationChannelTarget(node=1, path="scale")),
            gl.AnimationChannel(sampler=2, target=gl.AnimationChannelTarget(node=2, path="translation"))]),
            gl.Animation(name="still", samplers=[gl.AnimationSampler(input=2, output=3, interpolation="STEP")],
                         channels=[gl.AnimationChannel(sampler=0, target=gl.AnimationChannelTarget(
                             node=2, path="scale"))])],
        accessors=accessors, bufferViews=views, buffers=[gl.Buffer(byteLength=len(blob))])
    doc.set_binary_blob(blob)
    doc.save_binary(str(path))
    return path


def test_two_joint_file_matches_the_analytic_motion(tmp_path):
    take = load_gltf(_two_joints(tmp_path / "two.glb"), "bend", fps=4.0)
    assert take.model.joints == ("A", "B") and take.model.parents == (-1, 0)
    assert len(take) == 5 and take.fps == 4.0 and take.source.endswith("two.glb#bend")
    for i, t in enumerate(np.arange(5) / 4.0):
        theta = math.pi / 2 * t                                  # slerp: uniform angle
        scale = 1.0 if t < 0.5 else 3.0                          # STEP
        h = 2 * t ** 3 - 3 * t ** 2 + t                          # Hermite h10 + h11 with both tangents (1, 0, 0)
        local_b = scale * np.array([h, 1.0, 0.0])
        rotated = np.array([local_b[0] * math.cos(theta) - local_b[1] * math.sin(theta),
                            local_b[0] * math.sin(theta) + local_b[1] * math.cos(theta), 0.0])
        a = np.array([1.0, 2.0, 0.0])                            # base (1,0,0) + 2 * (0,1,0)
        np.testing.assert_allclose(take.positions[i, 0], a, atol=1e-6)
        np.testing.assert_allclose(take.positions[i, 1], a + 2.0 * rotated, atol=1e-6)


def test_animation_picked_by_name_index_fragment_and_listed(tmp_path):
    path = _two_joints(tmp_path / "two.glb")
    assert [(a.name, a.duration) for a in animations(path)] == [("bend", 1.0), ("still", 0.5)]
    assert load_take(f"{path}#still").source.endswith("#still")
    assert load_take(f"{path}#1").source.endswith("#still")
    assert load_take(path).source.endswith("#bend")
    with pytest.raises(BadMotionError, match=r"no animation named 'Walk' \(available: 0 'bend', 1 'still'\)"):
        load_take(f"{path}#Walk")
    with pytest.raises(BadMotionError, match="no animation #7"):
        load_take(f"{path}#7")


def test_sampler_clamps_and_slerps_the_short_way():
    times = np.array([0.0, 2.0])
    np.testing.assert_allclose(sample(times, np.array([[1.0], [3.0]]), "STEP", np.array([-1, 1.9, 2.0, 5])),
                               [[1], [1], [3], [3]])
    q0 = np.array([[0.0, 0.0, 0.0, 1.0]])
    q1 = -np.array([[0.0, math.sin(0.5), 0.0, math.cos(0.5)]])   # the same 1 rad turn, negated
    half = slerp(q0, q1, np.array([0.5]))
    assert abs(abs(half[0, 3]) - math.cos(0.25)) < 1e-12          # half of 1 rad, not of 2*pi - 1


def test_fox_walk_is_the_files_own_skeleton(data_dir):
    take = load_take(data_dir / "avatars" / "Fox.glb#Walk")
    assert take.model.name == "gltf:Fox"
    own = [j for j in take.model.joints if not j.endswith(".tip")]
    assert len(own) == 22 and take.model.joints[:22] == tuple(own)  # the two ground handles left out
    # the last joints that carry a skinned part (head, front paws, tail end) get a tip after the file's joints
    tips = take.model.joints[22:]
    assert sorted(tips) == ["b_Head_05.tip", "b_LeftHand_011.tip", "b_RightHand_08.tip", "b_Tail03_014.tip"]
    assert all(take.model.joints[take.model.parents[take.model.index(t)]] == t[:-4] for t in tips)
    assert take.model.joints[0] == "b_Hip_01" and take.model.parents[0] == -1
    head = take.model.index("b_Head_05")
    assert take.model.joints[take.model.parents[head]] == "b_Neck_04"
    feet = [take.model.index(n) for n in ("b_LeftFoot02_018", "b_RightFoot02_022")]
    # a walk: the hind feet swing back and forth along the body (z), on the ground (y near 0)
    assert np.ptp(take.positions[:, feet, 2], axis=0).min() > 15.0
    assert take.positions[:, feet, 1].min() < 3.0


def test_corrupt_and_animationless_files_are_named(tmp_path):
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"glTF" + struct.pack("<II", 2, 20) + b"\0" * 8)
    with pytest.raises(BadMotionError, match="bad.glb"):
        load_take(bad)
    with pytest.raises(BadMotionError, match="no such file"):
        load_take(tmp_path / "missing.glb#Walk")


def test_a_person_with_kinect_names_maps_to_kinect20(tmp_path):
    """A glTF person (here Z-up, joints named as Kinect-20) is mapped like a BVH person: Kinect-20, +Y up."""
    import kinetre
    model = kinetre.KINECT20
    # a standing T-pose in a Z-up file: height along +Z
    rest = {"HipCenter": (0, 0, 1.0), "Spine": (0, 0, 1.2), "ShoulderCenter": (0, 0, 1.45), "Head": (0, 0, 1.65)}
    for side, x in (("Left", 0.2), ("Right", -0.2)):
        rest.update({f"Shoulder{side}": (x, 0, 1.45), f"Elbow{side}": (2 * x, 0, 1.45),
                     f"Wrist{side}": (3 * x, 0, 1.45), f"Hand{side}": (3.4 * x, 0, 1.45),
                     f"Hip{side}": (x / 2, 0, 0.95), f"Knee{side}": (x / 2, 0, 0.5),
                     f"Ankle{side}": (x / 2, 0, 0.08), f"Foot{side}": (x / 2, 0.15, 0.0)})
    nodes = []
    for name, parent in zip(model.joints, model.parents):
        offset = np.subtract(rest[name], rest[model.joints[parent]]) if parent >= 0 else np.array(rest[name])
        nodes.append(gl.Node(name=name, translation=[float(v) for v in offset], children=[]))
    for j, parent in enumerate(model.parents):
        if parent >= 0:
            nodes[parent].children.append(j)
    times = np.array([0.0, 1.0], np.float32)
    moves = np.array([[0, 0, 1.0], [0.5, 0, 1.0]], np.float32)  # the hips slide 0.5 along +X
    blob = times.tobytes() + moves.tobytes()
    doc = gl.GLTF2(scene=0, scenes=[gl.Scene(nodes=[0])], nodes=nodes,
                   animations=[gl.Animation(name="slide", samplers=[gl.AnimationSampler(input=0, output=1)],
                                            channels=[gl.AnimationChannel(sampler=0, target=gl.AnimationChannelTarget(
                                                node=0, path="translation"))])],
                   accessors=[gl.Accessor(bufferView=0, componentType=gl.FLOAT, count=2, type="SCALAR",
                                          min=[0.0], max=[1.0]),
                              gl.Accessor(bufferView=1, componentType=gl.FLOAT, count=2, type="VEC3")],
                   bufferViews=[gl.BufferView(buffer=0, byteOffset=0, byteLength=8),
                                gl.BufferView(buffer=0, byteOffset=8, byteLength=24)],
                   buffers=[gl.Buffer(byteLength=len(blob))])
    doc.set_binary_blob(blob)
    doc.save_binary(str(tmp_path / "person.glb"))
    take = load_take(tmp_path / "person.glb", fps=2.0)
    assert take.model == kinetre.KINECT20 and len(take) == 3
    head, hips = take.model.index("Head"), take.model.index("HipCenter")
    np.testing.assert_allclose(take.positions[0, head] - take.positions[0, hips], [0, 0.65, 0], atol=1e-6)
    assert abs(take.frame(0).height - 1.65) < 1e-6
    np.testing.assert_allclose(take.positions[2, hips] - take.positions[0, hips], [0.5, 0, 0], atol=1e-6)
    own = load_take(tmp_path / "person.glb", as_kinect=False)
    assert own.model.name == "gltf:person" and own.model.joints == kinetre.KINECT20.joints


@pytest.mark.slow
def test_joints_that_move_no_skin_are_marked_and_their_bones_carry_nothing(data_dir):
    """The robot's artist weights its chest to the hips and leaves the spine links above them unweighted: the
    bones that turn with those links are not ones its skin follows; every weighted joint's bones are."""
    take = load_gltf(data_dir / "avatars" / "robot_quaternius.glb#Robot_Running", as_kinect=False)
    model = take.model
    assert {"Abdomen", "Torso", "Neck"} <= set(model.unskinned)
    assert not {"Hips", "Head", "UpperArm.L", "LowerLeg.R"} & set(model.unskinned)
    carries = dict(zip((f"{model.joints[p]}>{model.joints[c]}" for p, c in model.bones), model.skinning_bones))
    assert carries["Hips>Abdomen"] and carries["Head>Head.tip"] and carries["UpperLeg.L>LowerLeg.L"]
    assert not carries["Abdomen>Torso"] and not carries["Neck>Head"] and not carries["Torso>Shoulder.L"]
    fox = load_take(data_dir / "avatars" / "Fox.glb#Walk").model
    assert fox.skinning_bones.sum() >= len(fox.bones) - 1  # a skin that weights its whole skeleton keeps it
