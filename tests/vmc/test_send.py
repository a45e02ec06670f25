"""VMC out: a real UDP receiver on loopback decodes every bundle `kinetre avatar --vmc` streams."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from kinetre.avatar.retarget import retarget
from kinetre.cli import main
from kinetre.vmc.send import BONES, MIRROR, vmc_frames
from studio.vmc_receiver import vmc_receiver


def world_rotations(frame):
    """Compose the received local quaternions down Unity's hierarchy (still in Unity's axes)."""
    local = {name: Rotation.from_quat(q).as_matrix() for name, q in frame.items()}
    world = {}
    for name in local:
        parent = BONES[name][1]
        world[name] = local[name] if parent is None else world[parent] @ local[name]
    return world


def test_the_cli_streams_every_frame_in_order_with_unity_bones(tmp_path, capsys, data_dir):
    with vmc_receiver() as (port, bundles):
        code = main(["avatar", str(data_dir / "avatars" / "RiggedFigure.glb"), "--motion",
                     str(data_dir / "bvh" / "cmu_12_01_walk.bvh"), "--max-frames", "12", "--vmc", f"127.0.0.1:{port}"])
    assert code == 0 and "sent 12 VMC frames" in capsys.readouterr().out
    assert len(bundles) == 12
    times = []
    for messages in bundles:
        addresses = [a for a, _ in messages]
        assert addresses[:3] == ["/VMC/Ext/OK", "/VMC/Ext/T", "/VMC/Ext/Root/Pos"]
        assert addresses[-1] == "/VMC/Ext/Blend/Apply"
        bones = [p[0] for a, p in messages if a == "/VMC/Ext/Bone/Pos"]
        assert {"Hips", "Spine", "LeftUpperArm", "LeftLowerArm", "RightUpperLeg", "RightLowerLeg"} <= set(bones)
        assert set(bones) <= set(BONES)
        times.append(messages[1][1][0])
    assert np.allclose(np.diff(times), 1 / 30, atol=1e-6)


def test_received_rotations_carry_the_tracked_forearms_in_unity_axes(rigged, walk):
    avatar, bonemap, plan = rigged["RiggedFigure"]
    motion = retarget(plan, walk.positions, walk.tracked)
    frames = vmc_frames(plan, bonemap, motion)
    k = walk.model.joints
    for t in range(len(frames)):
        world = world_rotations({b: frames.rotations[t, i] for i, b in enumerate(frames.bones)})
        for side, sign in (("Left", 1.0), ("Right", -1.0)):
            tracked = walk.positions[t, k.index(f"Wrist{side}")] - walk.positions[t, k.index(f"Elbow{side}")]
            expected = MIRROR @ (tracked / np.linalg.norm(tracked))
            # the T-pose forearm points along the avatar's side: +X for its left (glTF) = -X in Unity
            got = world[f"{side}LowerArm"] @ np.array([-sign, 0.0, 0.0])
            assert np.degrees(np.arccos(np.clip(got @ expected, -1, 1))) < 2.0


def test_a_known_elbow_bend_is_a_quarter_turn_towards_unity_forward(rigged, walk):
    avatar, bonemap, plan = rigged["RiggedFigure"]
    pos = walk.positions[:1].copy()
    k = walk.model.joints
    e, w = k.index("ElbowLeft"), k.index("WristLeft")
    s = k.index("ShoulderLeft")
    # upper arm straight out to the left (+X in Kinetre), forearm bent forward (+Z)
    pos[0, e] = pos[0, s] + [0.3, 0.0, 0.0]
    pos[0, w] = pos[0, e] + [0.0, 0.0, 0.25]
    motion = retarget(plan, pos, walk.tracked[:1])
    frames = vmc_frames(plan, bonemap, motion)
    world = world_rotations({b: frames.rotations[0, i] for i, b in enumerate(frames.bones)})
    upper, lower = world["LeftUpperArm"], world["LeftLowerArm"]
    bend = Rotation.from_matrix(upper.T @ lower).magnitude()
    assert abs(np.degrees(bend) - 90.0) < 2.0
    assert np.allclose(lower @ [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], atol=0.03)


def test_a_takes_face_streams_as_vrm_blendshape_clips(tmp_path, capsys, data_dir, walk):
    from kinetre.motion.stream import write_stream
    from kinetre.motion.take import Take
    t = 6
    names = ("_neutral", "jawOpen", "eyeBlinkLeft", "eyeBlinkRight", "cheekPuff")
    faces = np.stack([np.zeros(t), np.linspace(0, 1, t), np.full(t, 0.9), np.full(t, 0.5), np.full(t, 0.25)], 1)
    take = Take(walk.model, walk.positions[:t], walk.tracked[:t], 30.0, "face", people=(0,),
                crowd_positions=walk.positions[:t, None], crowd_tracked=walk.tracked[:t, None],
                blendshapes=faces[:, None], blendshape_names=names)
    path = tmp_path / "face.kinetre.jsonl"
    write_stream(path, take)
    with vmc_receiver() as (port, bundles):
        code = main(["avatar", str(data_dir / "avatars" / "RiggedFigure.glb"), "--motion", str(path),
                     "--vmc", f"127.0.0.1:{port}"])
    assert code == 0 and "8 blendshapes" in capsys.readouterr().out
    assert len(bundles) == t
    for k, messages in enumerate(bundles):
        blend = {p[0]: p[1] for a, p in messages if a == "/VMC/Ext/Blend/Val"}
        # the VRM 0.x presets, then every ARKit name as perfect-sync senders give it
        assert set(blend) == {"A", "Blink", "Blink_L", "Blink_R", "jawOpen", "eyeBlinkLeft", "eyeBlinkRight",
                              "cheekPuff"}
        assert abs(blend["A"] - k / (t - 1)) < 1e-6 and abs(blend["Blink"] - 0.5) < 1e-6
        assert abs(blend["Blink_L"] - 0.4) < 1e-6 and blend["Blink_R"] == 0.0
        assert abs(blend["jawOpen"] - k / (t - 1)) < 1e-6 and abs(blend["eyeBlinkLeft"] - 0.9) < 1e-6
        assert [a for a, _ in messages][-1] == "/VMC/Ext/Blend/Apply"
