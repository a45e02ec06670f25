"""Fidelity against an artist's rig, judged by the independent glTF player (tests/export/gltf_player.py): an
avatar's body posed at the first frame of one of its own clips, written as an unrigged mesh and driven by
`kinetre animate --motion AVATAR.glb#CLIP` with the defaults, must follow the avatar's own skin (errors in %
of its height, at a few frames); `kinetre avatar` driven by the avatar's own clip must reproduce it."""
from __future__ import annotations

import pytest

from export.fidelity import Clip
from kinetre.cli import main

FRAMES = 8

# (avatar, clip, bound on the mean error in % of height). Each bound is well below what standing still scores
# on that clip (checked below), so a rig that does not follow the motion fails.
ANIMATE = [("RiggedFigure", "0", 2.2), ("Fox", "Walk", 5.5), ("CesiumMan", "0", 1.2),
           ("robot_quaternius", "Robot_Walking", 1.0), ("robot_quaternius", "Robot_Dance", 1.0),
           ("robot_quaternius", "Robot_Running", 1.2), ("robot_quaternius", "Robot_Death", 1.2)]
AVATAR = [("RiggedFigure", "0", 0.5), ("CesiumMan", "0", 1.5), ("robot_quaternius", "Robot_Walking", 0.5)]
# `make check` keeps the two small rigs (RiggedFigure, Fox) and leaves the larger ones to `make test`
QUICK = ("RiggedFigure", "Fox")
ANIMATE = [c if c[0] in QUICK else pytest.param(*c, marks=pytest.mark.slow) for c in ANIMATE]
AVATAR = [c if c[0] in QUICK else pytest.param(*c, marks=pytest.mark.slow) for c in AVATAR]


@pytest.mark.parametrize("avatar,clip,bound", ANIMATE)
def test_an_unrigged_mesh_follows_the_artists_rig(data_dir, tmp_path, avatar, clip, bound):
    take = Clip(data_dir / "avatars" / f"{avatar}.glb", clip, FRAMES)
    mesh = take.write_mesh(tmp_path / "posed.ply")
    out = tmp_path / "out.glb"
    assert main(["animate", str(mesh), "--motion", f"{take.path}#{clip}", "-o", str(out), "-q"]) == 0
    got, gap = take.compare_mesh_animation(out)
    assert gap < 1e-4                       # every written vertex found at its rest position
    assert got["still_mean_pct"] > 1.15 * bound
    assert got["mean_pct"] <= bound, got
    assert got["worst_frame_pct"] < got["still_worst_frame_pct"], got


@pytest.mark.parametrize("avatar,clip,bound", AVATAR)
def test_an_avatar_driven_by_its_own_clip_reproduces_it(data_dir, tmp_path, avatar, clip, bound):
    take = Clip(data_dir / "avatars" / f"{avatar}.glb", clip, FRAMES)
    out = tmp_path / "own.glb"
    assert main(["avatar", str(take.path), "--motion", f"{take.path}#{clip}", "-o", str(out), "-q"]) == 0
    got = take.compare_avatar_animation(out)
    assert got["still_mean_pct"] > 4 * bound
    assert got["mean_pct"] <= bound, got


def test_the_nearest_bone_rig_follows_the_motion_and_standing_still_does_not(data_dir):
    """The reference measures themselves: the artist's own skin scores zero, holding the first frame scores
    what the clip moves, and a rigid nearest-bone rig lands in between."""
    take = Clip(data_dir / "avatars" / "CesiumMan.glb", "0", FRAMES)
    assert take.still[0].max() == 0.0 and take.still.mean() > 3.0      # the walk moves the body
    rigid = take.nearest_bone()
    assert rigid["beats_still"] and rigid["mean_pct"] < 0.5 * rigid["still_mean_pct"], rigid
    assert rigid["mean_pct"] > 0.05                                   # not the artist skin itself
