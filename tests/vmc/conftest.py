"""Fixtures for the avatar tests: the humanoid avatars of ../shared/data/avatars, mapped and planned once,
and a CMU walk clip (30 fps, 2 s)."""
from __future__ import annotations

import pytest

from kinetre.avatar.bonemap import map_bones
from kinetre.avatar.load import load_avatar
from kinetre.avatar.retarget import plan_retarget
from kinetre.motion.bvh import load_bvh
from kinetre.motion.source import resample

HUMANOIDS = ("RiggedFigure", "CesiumMan", "robot_quaternius")


@pytest.fixture(scope="session")
def rigged(data_dir):
    """name -> (avatar, bonemap, plan) for each humanoid."""
    out = {}
    for name in HUMANOIDS:
        avatar = load_avatar(data_dir / "avatars" / f"{name}.glb")
        bonemap = map_bones(avatar)
        out[name] = (avatar, bonemap, plan_retarget(avatar, bonemap))
    return out


@pytest.fixture(scope="session")
def walk(data_dir):
    return resample(load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh"), 30.0).slice(0, 60)
