"""VMC through a running studio (`run_studio` in a subprocess, headless, the sample walk driving):
`--vmc`: an uploaded avatar sends its live pose, every UDP message decoded on loopback;
`--vmc-listen`: packets recorded from Kinetre's own sender make a user who possesses and moves the mesh."""
from __future__ import annotations

import asyncio
import socket
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from studio.conftest import start_server
from kinetre.avatar.bonemap import map_bones
from kinetre.avatar.load import load_avatar
from kinetre.avatar.retarget import plan_retarget, retarget
from kinetre.motion.bvh import load_bvh
from kinetre.motion.source import resample
from kinetre.skeleton.models import KINECT20
from kinetre.studio.meshes import data_path
from kinetre.vmc.send import BONES, MIRROR, frame_bundle, vmc_frames
from studio.studio_ws import StudioClient
from studio.vmc_receiver import vmc_receiver

pytestmark = pytest.mark.slow  # a studio server process in every test

LIMBS = {"LeftLowerArm": ("ElbowLeft", "WristLeft", (1.0, 0.0, 0.0)),
         "RightLowerArm": ("ElbowRight", "WristRight", (-1.0, 0.0, 0.0)),
         "LeftLowerLeg": ("KneeLeft", "AnkleLeft", (0.0, -1.0, 0.0)),
         "RightLowerLeg": ("KneeRight", "AnkleRight", (0.0, -1.0, 0.0))}


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def sample_directions():
    """(T, 4, 3) forearm and shin directions of every frame of the studio's sample walk."""
    take = load_bvh(str(data_path("cmu_12_01_walk.bvh")))
    k = KINECT20.joints
    return np.stack([unit(take.positions[:, k.index(b)] - take.positions[:, k.index(a)])
                     for a, b, _ in LIMBS.values()], axis=1)


def udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def receiver():
    with vmc_receiver() as received:
        yield received


def test_studio_avatars_send_the_driving_walk_as_vmc(receiver, data_dir):
    import httpx
    port, bundles = receiver
    proc, url = start_server(sample_motion=True, nodes=64, timeout=600, vmc=("127.0.0.1", port))
    try:
        r = httpx.post(f"{url}/api/avatar", params={"name": "RiggedFigure.glb"},
                       content=(data_dir / "avatars" / "RiggedFigure.glb").read_bytes(), timeout=60)
        assert r.status_code == 200 and r.json()["id"] == 1
        deadline = time.monotonic() + 60
        while len(bundles) < 40 and time.monotonic() < deadline:
            time.sleep(0.1)
    finally:
        proc.terminate()
        proc.wait(10)
    assert len(bundles) >= 40
    walk = sample_directions()
    times, poses = [], []
    for messages in bundles:
        addresses = [a for a, _ in messages]
        assert addresses[:3] == ["/VMC/Ext/OK", "/VMC/Ext/T", "/VMC/Ext/Root/Pos"]
        assert addresses[-1] == "/VMC/Ext/Blend/Apply"
        assert set(addresses[3:-1]) == {"/VMC/Ext/Bone/Pos"}
        local = {p[0]: Rotation.from_quat(p[4:8]).as_matrix() for a, p in messages if a == "/VMC/Ext/Bone/Pos"}
        assert {"Hips", "Spine", *LIMBS} <= set(local) <= set(BONES)
        world = {}
        for name in local:                                     # parents come first
            parent = BONES[name][1]
            world[name] = local[name] if parent is None else world[parent] @ local[name]
        # each T-pose limb direction as posed, back in Kinetre's axes
        got = np.array([MIRROR @ world[b] @ MIRROR @ np.array(t) for b, (_, _, t) in LIMBS.items()])
        # the frame of the sample walk this bundle shows: all four limbs within 2 degrees of it
        worst = np.degrees(np.arccos(np.clip(np.einsum("tlc,lc->tl", walk, got), -1, 1))).max(axis=1)
        assert worst.min() < 2.0
        poses.append(int(worst.argmin()))
        times.append(messages[1][1][0])
    assert np.all(np.diff(times) > 0)
    assert len(set(poses)) >= 10                                # it walks


def test_a_vmc_performer_becomes_a_user_who_possesses_and_moves_the_mesh(data_dir):
    port = udp_port()
    proc, url = start_server(sample_motion=True, nodes=64, timeout=600, vmc_listen=("127.0.0.1", port))
    avatar = load_avatar(data_dir / "avatars" / "CesiumMan.glb")
    bonemap = map_bones(avatar)
    plan = plan_retarget(avatar, bonemap)
    walk = resample(load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh"), 30.0)
    frames = 45
    vmc = vmc_frames(plan, bonemap, retarget(plan, walk.positions[:frames], walk.tracked[:frames]))
    packets = [frame_bundle(vmc, k, k / 30) for k in range(frames)]
    k = KINECT20.joints
    source = np.stack([unit(walk.positions[:frames, k.index(b)] - walk.positions[:frames, k.index(a)])
                       for a, b, _ in LIMBS.values()], axis=1)

    async def perform():
        async with StudioClient(url) as c:
            await c.send({"type": "subscribe", "skeletons": True})
            out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            moved = []
            for i, p in enumerate(packets):
                out.sendto(p, ("127.0.0.1", port))
                await asyncio.sleep(1 / 30)
                user = next((u for u in c.state["users"] if u["client"] == "vmc1"), None)
                if user is not None and user["possessing"]:
                    moved.append(c.matrices().copy())
            out.close()
            await c.wait(lambda c: any(u["client"] == "vmc1" and u["frames"] >= frames // 2
                                       for u in c.state["users"]), 30)
            return c.state, [m for m in c.messages if m["type"] == "skeleton" and m.get("client") == "vmc1"], moved

    try:
        state, skeletons, moved = asyncio.run(perform())
    finally:
        proc.terminate()
        proc.wait(10)
    users = {u["client"]: u for u in state["users"]}
    assert users["vmc1"]["possessing"]
    assert not users.get("sample", {"possessing": False})["possessing"]   # the performer took over
    assert len(skeletons) >= frames // 2
    for m in skeletons:
        p = np.array([np.nan * np.ones(3) if q is None else q for q in m["positions"]])
        got = np.stack([unit(p[k.index(b)] - p[k.index(a)]) for a, b, _ in LIMBS.values()])
        worst = np.degrees(np.arccos(np.clip(np.einsum("tlc,lc->tl", source, got), -1, 1))).max(axis=1)
        assert worst.min() < 0.5                            # each frame is one of the walk's, limb for limb
    assert len(moved) >= 10
    assert max(np.abs(m - moved[0]).max() for m in moved) > 1e-2   # the possessed mesh moves with it


def test_bad_vmc_addresses_are_one_line_errors(capsys):
    from kinetre.cli import main
    assert main(["studio", "--no-browser", "--vmc", "127.0.0.1:port"]) == 2
    assert "--vmc 127.0.0.1:port: the port must be a number" in capsys.readouterr().err
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        assert main(["studio", "--no-browser", "--vmc-listen", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"--vmc-listen 127.0.0.1:{port}: cannot listen there" in err and err.count("\n") == 1
