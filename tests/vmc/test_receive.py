"""VMC in: packets recorded from Kinetre's own sender (an avatar retargeted from a BVH walk) and sent on
loopback come back through the python-osc listener as Kinect-20 skeletons whose limbs point where the
walk's do."""
from __future__ import annotations

import asyncio
import socket

import numpy as np
from pythonosc.osc_packet import OscPacket

from kinetre.avatar.retarget import retarget
from kinetre.vmc.receive import VmcListener, VmcSkeletons, world_positions
from kinetre.vmc.send import frame_bundle, vmc_frames

LIMBS = [("ShoulderLeft", "ElbowLeft"), ("ElbowLeft", "WristLeft"), ("ShoulderRight", "ElbowRight"),
         ("ElbowRight", "WristRight"), ("HipLeft", "KneeLeft"), ("KneeLeft", "AnkleLeft"),
         ("HipRight", "KneeRight"), ("KneeRight", "AnkleRight")]


def direction(positions, joints, a, b):
    v = positions[joints.index(b)] - positions[joints.index(a)]
    return v / np.linalg.norm(v)


def recorded(rigged, walk, name="CesiumMan", frames=20):
    avatar, bonemap, plan = rigged[name]
    vmc = vmc_frames(plan, bonemap, retarget(plan, walk.positions[:frames], walk.tracked[:frames]))
    return [frame_bundle(vmc, k, k / 30) for k in range(frames)]


async def send_and_listen(packets, gap=0.005):
    got = []
    listener = VmcListener(lambda address, skeleton, face: got.append((address, skeleton)), port=0)
    await listener.start()
    out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for p in packets:
        out.sendto(p, ("127.0.0.1", listener.port))
        await asyncio.sleep(gap)
    await asyncio.sleep(0.2)
    out.close()
    listener.close()
    return got, listener


def test_recorded_packets_on_loopback_become_the_walks_limbs(rigged, walk):
    for name in ("CesiumMan", "RiggedFigure"):
        packets = recorded(rigged, walk, name)
        got, listener = asyncio.run(send_and_listen(packets))
        assert len(got) == len(packets) == listener.packets and len({a for a, _ in got}) == 1
        joints = walk.model.joints
        for k, (_, skeleton) in enumerate(got):
            assert skeleton.model.name == "kinect20" and skeleton.tracked.all()
            for a, b in LIMBS:
                cos = direction(skeleton.positions, joints, a, b) @ direction(walk.positions[k], joints, a, b)
                assert np.degrees(np.arccos(np.clip(cos, -1, 1))) < 0.5, (name, k, a, b)
            # standing on the floor: the hips above the ankles by about the leg
            assert skeleton.positions[joints.index("HipCenter"), 1] > skeleton.positions[joints.index("AnkleLeft"), 1]


def test_loose_messages_end_a_frame_at_T_and_garbage_is_ignored(rigged, walk):
    bundle = recorded(rigged, walk, frames=1)[0]
    loose = [m.message.dgram for m in OscPacket(bundle).messages]
    assert [OscPacket(d).messages[0].message.address for d in loose[:2]] == ["/VMC/Ext/OK", "/VMC/Ext/T"]
    # a loose-message performer: T first (no bones yet: no frame), then the bones, then Blend/Apply ends it
    got, listener = asyncio.run(send_and_listen([b"not osc at all", *loose, *loose]))
    assert len(got) == 2 and listener.packets == 2 * len(loose)


def test_bones_compose_on_their_nearest_sent_ancestor():
    turn = [0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)]          # 90 degrees about Unity's +Z
    bones = {"Hips": ([0.0, 1.0, 0.0], [0, 0, 0, 1]), "Spine": ([0.0, 0.1, 0.0], [0, 0, 0, 1]),
             "Chest": ([0.0, 0.2, 0.0], turn), "LeftShoulder": ([-0.05, 0.2, 0.0], [0, 0, 0, 1]),
             "LeftUpperArm": ([-0.1, 0.0, 0.0], [0, 0, 0, 1])}
    names, parents, pos = world_positions(bones, ([0.0, 0.0, 1.0], [0, 0, 0, 1]))
    assert names == ("Hips", "Spine", "Chest", "LeftShoulder", "LeftUpperArm")
    assert parents == [-1, 0, 1, 2, 3]                # LeftShoulder hangs on Chest (no UpperChest sent)
    assert np.allclose(pos[0], [0.0, 1.0, 1.0]) and np.allclose(pos[2], [0.0, 1.3, 1.0])
    # Unity's +Z turn is a turn about -Z here (mirrored): the shoulder's Unity (-0.05, 0.2) offset, on our
    # +X side (the avatar's left), turns to point down and left
    assert np.allclose(pos[3], pos[2] + [0.2, -0.05, 0.0])


def test_a_skeleton_needs_hips_and_numbers():
    s = VmcSkeletons()
    s.start_packet(True)
    s.message("/VMC/Ext/Bone/Pos", ["Hips", "x", 0, 0, 0, 0, 0, 1])          # not numbers: ignored
    s.message("/VMC/Ext/Bone/Pos", ["Spine", 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 1.0])
    assert s.end_of_packet(True) is None and "Hips" not in s.bones
