"""A hand puppet: a take's hand as a 21-joint skeleton (MediaPipe's hand landmarks) possessing a mesh, the
fingers as its legs. Analytic fingers bending in a five-legged creature, and a real capture."""
from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.spatial.distance import pdist
from export.gltf_player import GltfPlayer
from synthetic import PHALANX, REST, hand_creature, spread_hand, tpose

import kinetre
from kinetre.cli import main
from kinetre.animation import AnimateSettings, animate
from kinetre.errors import BadMotionError
from kinetre.mesh.load import mesh_from_trimesh
from kinetre.motion.hands import HAND_LENGTH, fit_puppet, hand_length, hand_take, hang_rotation
from kinetre.motion.stream import read_stream, write_stream
from kinetre.motion.take import Take
from kinetre.skeleton.models import FINGER_JOINTS, HAND21, MODELS, Skeleton

MEDIAPIPE_ORDER = ("wrist", "thumb_cmc", "thumb_mcp", "thumb_ip", "thumb_tip", "index_mcp", "index_pip",
                   "index_dip", "index_tip", "middle_mcp", "middle_pip", "middle_dip", "middle_tip", "ring_mcp",
                   "ring_pip", "ring_dip", "ring_tip", "pinky_mcp", "pinky_pip", "pinky_dip", "pinky_tip")
TIPS = [HAND21.index(chain[-1]) for chain in FINGER_JOINTS.values()]
@pytest.fixture(scope="module")
def creature():
    """The five-legged creature (`synthetic.hand_creature`) as a mesh, and its leg tips."""
    surface, feet = hand_creature()
    return mesh_from_trimesh(surface, "creature"), feet


def test_the_hand_skeleton_is_mediapipes_21_landmarks_with_a_chain_per_finger():
    assert HAND21.joints == MEDIAPIPE_ORDER and MODELS["hand21"] is HAND21
    assert len(HAND21.bones) == 20
    assert [HAND21.joints[i] for i, p in enumerate(HAND21.parents) if p < 0] == ["wrist"]
    for chain in FINGER_JOINTS.values():
        idx = [HAND21.index(j) for j in chain]
        assert [HAND21.parents[i] for i in idx] == [0] + idx[:-1]     # wrist -> base -> ... -> tip
    children = np.bincount([p for p in HAND21.parents if p >= 0], minlength=21)
    assert children[0] == 5 and set(children[TIPS]) == {0}
    assert kinetre.subset_mask(HAND21, "index").sum() == 4
    assert kinetre.subset_mask(HAND21, ["pinky", "wrist"]).sum() == 5
    assert kinetre.subset_mask(HAND21, "fingers").sum() == 20 and kinetre.subset_mask(HAND21, "palm").sum() == 6
    with pytest.raises(kinetre.BadSkeletonError, match="thumb, index"):
        kinetre.subset_mask(HAND21, "elbow")


def _camera_take(hands: np.ndarray, source="camera.kinetre.jsonl") -> Take:
    """A one-person camera take (a person standing in a T-pose) carrying `hands` (T, 2, 21, 3)."""
    t = len(hands)
    body = np.repeat(tpose().positions[None], t, axis=0)
    seen = np.ones((t, 20), bool)
    return Take(kinetre.KINECT20, body, seen, 10.0, source, (0,), body[:, None], seen[:, None], hands[:, None])


def test_a_takes_hand_becomes_a_hand_take_at_real_size(tmp_path):
    curls = np.radians([30.0, 20.0, 10.0])
    right = np.stack([spread_hand(np.full(5, c)) for c in curls])
    hands = np.full((3, 2, 21, 3), np.nan)
    hands[:, 1] = right
    hands[1, 0] = right[1] + [0.3, 0.0, 0.0]  # the left hand is seen once
    take = _camera_take(hands)
    length = hand_length(right)
    assert length == pytest.approx(0.035 + PHALANX.sum())
    hand = hand_take(take, "right")
    assert hand.model is HAND21 and hand.tracked.all()
    np.testing.assert_array_equal(hand.positions, right)   # metres: kept as recorded
    left = hand_take(take, "left")
    assert left.tracked.sum(axis=1).tolist() == [0, 21, 0]
    # the same hand in pixels (a 1000-pixel-wide image): scaled to a real hand, its shape kept
    pixels = hand_take(_camera_take(hands * 1000.0), "right")
    assert hand_length(pixels.positions) == pytest.approx(HAND_LENGTH)
    shape = (pixels.positions - pixels.positions[:, :1]) / HAND_LENGTH
    np.testing.assert_allclose(shape, (right - right[:, :1]) / length, atol=1e-12)
    # a written hand take reads back as the built-in hand skeleton
    path = tmp_path / "hand.kinetre.jsonl"
    write_stream(path, hand)
    again = read_stream(path)
    assert again.model is HAND21
    np.testing.assert_array_equal(again.positions, hand.positions)


def test_a_take_without_hands_is_refused_naming_the_file(data_dir):
    walk = kinetre.load_take(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    with pytest.raises(BadMotionError, match=r"\.bvh: records no hands"):
        hand_take(walk, "right")
    hands = np.full((2, 2, 21, 3), np.nan)
    hands[:, 0] = spread_hand(np.full(5, REST))
    with pytest.raises(BadMotionError, match="camera.kinetre.jsonl: the right hand of the main person is not seen"):
        hand_take(_camera_take(hands), "right")
    with pytest.raises(BadMotionError, match="left or right"):
        hand_take(_camera_take(hands), "both")


def test_a_hand_held_up_is_turned_so_its_fingers_hang():
    hanging = spread_hand(np.full(5, REST))
    assert np.allclose(hang_rotation(Skeleton.from_positions(HAND21, hanging)), np.eye(3))
    # the same hand held up to a camera, fingers pointing up and a little towards it
    up = hanging @ np.array([[1.0, 0.0, 0.0], [0.0, -0.9, -0.43], [0.0, 0.43, -0.9]]).T
    turn = hang_rotation(Skeleton.from_positions(HAND21, up))
    turned = up @ turn.T
    tips, palm = turned[TIPS].mean(axis=0), turned[[0, 1, 5, 9, 13, 17]].mean(axis=0)
    down = (tips - palm) / np.linalg.norm(tips - palm)
    np.testing.assert_allclose(down, [0.0, -1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(turn @ turn.T, np.eye(3), atol=1e-12)


def _finger_frames() -> np.ndarray:
    """(6, 21, 3) frame 0 the bind pose; in frame f + 1 finger f alone straightens from 30° to 8° a joint: its
    tip lifts up and out, the others stay."""
    frames = [spread_hand(np.full(5, REST))]
    for f in range(5):
        curl = np.full(5, REST)
        curl[f] = np.radians(8.0)
        frames.append(spread_hand(curl))
    return np.stack(frames)


def _tips_to_feet(result, feet) -> np.ndarray:
    """(5, 5) distances from each placed fingertip in the bind frame to each leg's tip (the mesh's units)."""
    return np.linalg.norm(result.take.positions[0, TIPS][:, None] - feet[None], axis=2)


@pytest.mark.slow
def test_each_finger_walks_its_own_leg_of_a_five_legged_creature(creature):
    mesh, feet = creature
    take = Take(HAND21, _finger_frames(), np.ones((6, 21), bool), 10.0, "hand")
    result = animate(mesh, take, AnimateSettings(nodes=128))
    assert result.placement.method == "shapes" and result.upright.up == "y" and not result.notes
    placed = result.take.positions                    # the hand in the mesh's units
    # the fit put every fingertip in its own leg: the nearest leg tip, within a leg's thickness (0.066; the
    # legs are 0.5 long)
    d = _tips_to_feet(result, feet)
    assert d.argmin(axis=1).tolist() == [0, 1, 2, 3, 4], np.round(d, 3)
    assert d.min(axis=1).max() < 0.1, np.round(d.min(axis=1), 3)
    rest = kinetre.skin(result.mesh, result.graph, result.poses[0])
    np.testing.assert_allclose(rest, mesh.vertices, atol=1e-3 * np.ptp(mesh.vertices, axis=0).max())
    feet_at = [np.linalg.norm(mesh.vertices - foot, axis=1) < 0.09 for foot in feet]
    for f in range(5):
        moved = kinetre.skin(result.mesh, result.graph, result.poses[f + 1]) - rest
        tip = placed[f + 1, TIPS[f]] - placed[0, TIPS[f]]
        leg = moved[feet_at[f]].mean(axis=0)
        cosine = leg @ tip / (np.linalg.norm(leg) * np.linalg.norm(tip))
        ratio = np.linalg.norm(leg) / np.linalg.norm(tip)
        assert cosine > 0.95 and 0.6 < ratio < 1.3, f"finger {f}: cos {cosine:.3f}, leg/finger {ratio:.2f}"
        others = max(np.linalg.norm(moved[feet_at[g]].mean(axis=0)) for g in range(5) if g != f)
        assert others < 0.2 * np.linalg.norm(tip), f"finger {f} moves another leg by {others:.3f}"


def test_a_hand_held_up_is_turned_over_to_walk_the_creature(creature):
    mesh, feet = creature
    # the same hand held up to a camera: fingers up, leaning away from it
    a = np.radians(160.0)
    up = _finger_frames() @ np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]]).T
    take = Take(HAND21, up, np.ones((6, 21), bool), 10.0, "hand")
    turned = _tips_to_feet(animate(mesh, take, AnimateSettings(nodes=64, solve=False)), feet)
    held = _tips_to_feet(animate(mesh, take, AnimateSettings(nodes=64, solve=False, hang=False)), feet)
    # turned over, every fingertip lands in its own leg (the hand hangs straight down where the creature's
    # legs lean out 25°, so a tip may sit a little off its leg's end); as held, the fingers point up, the
    # legs down: no fingertip is near any leg's tip
    assert turned.argmin(axis=1).tolist() == [0, 1, 2, 3, 4], np.round(turned, 3)
    assert turned.min(axis=1).max() < 0.2, np.round(turned.min(axis=1), 3)
    assert held.min(axis=1).min() > 0.2, np.round(held.min(axis=1), 3)


@pytest.fixture(scope="module")
def captured(data_dir, tmp_path_factory):
    """`kinetre capture` on a real photo seen by a camera that pans and closes in over 8 frames (both hands
    hang by the woman's sides): the take, with hands."""
    import cv2
    folder = tmp_path_factory.mktemp("hands")
    image = cv2.imread(str(data_dir / "images" / "pose" / "standing_woman.png"))
    h, w = image.shape[:2]
    video = folder / "pan.mp4"
    out = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (w, h))
    for k in range(8):
        s, dx = 1.0 + 0.03 * k, 6.0 * k
        zoom = np.array([[s, 0.0, (1.0 - s) * w / 2 + dx], [0.0, s, (1.0 - s) * h / 2]])
        out.write(cv2.warpAffine(image, zoom, (w, h), borderMode=cv2.BORDER_REPLICATE))
    out.release()
    take = folder / "pan.kinetre.jsonl"
    assert main(["capture", "--video", str(video), "--no-face", "-o", str(take)]) == 0
    return take


@pytest.mark.slow
def test_a_captured_hand_possesses_a_real_mesh(captured, data_dir, tmp_path, capsys):
    capsys.readouterr()
    assert main(["info", str(captured)]) == 0
    info = capsys.readouterr().out
    assert re.search(r"person 0: left in 8 frames \(1\d cm\), right in 8 frames \(1\d cm\)", info), info
    assert "index: wrist -> index_mcp -> index_pip -> index_dip -> index_tip" in info

    spot = data_dir / "meshes" / "spot.obj"
    out, placed = tmp_path / "spot.glb", tmp_path / "placed.kinetre.jsonl"
    for target in (out, placed):
        args = ["animate", str(spot), "--motion", str(captured), "--hand", "right", "--nodes", "96", "-q"]
        assert main(args + ["-o", str(target)]) == 0
    player = GltfPlayer(out)
    frames = np.stack([player.skin(t) for t in player.tracks[0][3]])
    assert frames.shape[0] == 8 and np.isfinite(frames).all()
    rest = kinetre.load_mesh(spot).vertices
    np.testing.assert_allclose(frames[0], rest, atol=0.02 * np.ptp(rest, axis=0).max())
    # the camera closes in and pans: the hand travels, and the cow goes with it, as far and the same way
    hand = read_stream(placed)
    assert hand.model is HAND21 and hand.tracked.all()
    travel = hand.positions[-1].mean(axis=0) - hand.positions[0].mean(axis=0)   # the mesh's units
    moved = (frames[-1] - frames[0]).mean(axis=0)
    cosine = moved @ travel / (np.linalg.norm(moved) * np.linalg.norm(travel))
    ratio = np.linalg.norm(moved) / np.linalg.norm(travel)
    assert np.linalg.norm(travel) > 0.2 * np.ptp(rest, axis=0).max(), travel
    assert cosine > 0.9 and 0.6 < ratio < 1.4, f"cos {cosine:.3f}, mesh/hand travel {ratio:.2f}"


def test_hand_errors_name_the_file(captured, data_dir, capsys):
    spot = str(data_dir / "meshes" / "spot.obj")
    walk = str(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    for argv, words in ((["--motion", walk, "--hand", "right"], f"{walk}: records no hands"),
                        (["--motion", str(captured), "--hand", "left", "--person", "4"],
                         f"{captured}: no person 4"),
                        (["--motion", str(captured), "--hand", "left", "--hand", "right"], "a --map JSON")):
        code = main(["animate", spot, *argv, "-o", "never.glb"])
        lines = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and words in lines[0], lines


def test_two_hands_share_a_mesh_through_a_joint_map(captured, data_dir, tmp_path):
    jmap = tmp_path / "two-hands.json"
    jmap.write_text('{"sources": [{"prefix": "left_"}, {"prefix": "right_", "keep": ["wrist", "index", "middle"]}]}')
    placed = tmp_path / "placed.kinetre.jsonl"
    args = ["animate", str(data_dir / "meshes" / "spot.obj"), "--motion", str(captured), "--hand", "left",
            "--hand", "right", "--map", str(jmap), "-q", "-o", str(placed)]
    assert main(args) == 0
    take = read_stream(placed)
    names = ["left_" + j for j in HAND21.joints] + ["right_" + j for j in ("wrist",) + FINGER_JOINTS["index"]
                                                    + FINGER_JOINTS["middle"]]
    assert list(take.model.joints) == names and take.tracked.all()
    assert take.model.parents[names.index("right_index_mcp")] == names.index("right_wrist")
    # the two hands keep where they were held relative to each other: the placed skeleton is the two
    # recorded hands under one scale and turn
    recorded = kinetre.load_take(captured)
    kept = [HAND21.index(j) for j in ("wrist",) + FINGER_JOINTS["index"] + FINGER_JOINTS["middle"]]
    both = np.concatenate([hand_take(recorded, "left").positions[0],
                           hand_take(recorded, "right").positions[0, kept]])
    ratio = pdist(take.positions[0]) / pdist(both)
    assert np.ptp(ratio) < 1e-6 * ratio.mean()
    apart = np.linalg.norm(both[0] - both[21])
    assert 0.1 < apart < 0.8, f"the wrists are {apart:.2f} m apart"


def test_a_live_hand_is_put_in_the_mesh_in_its_own_frame(creature):
    mesh, feet = creature
    hand = Skeleton.from_positions(HAND21, spread_hand(np.full(5, REST)) + [0.3, 1.2, -0.5])  # a webcam's metres
    fitted = fit_puppet(hand, mesh)
    inside = fitted.place(hand).positions
    d = np.linalg.norm(inside[TIPS][:, None] - feet[None], axis=2)
    assert d.argmin(axis=1).tolist() == [0, 1, 2, 3, 4] and d.min(axis=1).max() < 0.1, np.round(d, 3)
    np.testing.assert_allclose(fitted.rotation @ fitted.rotation.T, np.eye(3), atol=1e-12)
    assert fitted.scale == pytest.approx(3.0, rel=0.3)   # the creature is 3x the hand
    # in the fit's frame the creature's longest side is a person's height (its legs 0.5 of 0.58 units long)
    assert fitted.metre == pytest.approx(np.ptp(mesh.vertices, axis=0).max() / 1.7, rel=0.5)
