"""`kinetre info FILE`: what a mesh, glTF, BVH, take or video holds, and how the other commands can use it;
for every skeleton (BVH, glTF animation, avatar, take) the map to Kinect-20: which source joint plays which
joint, which are derived, which are untracked and why."""
from __future__ import annotations

import os
from pathlib import Path

from .common import VIDEO_EXTS, UsageError


def register(sub) -> None:
    """Add `kinetre info` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("info", help="what a mesh, BVH, take or video holds")
    p.add_argument("path")
    p.set_defaults(func=cmd_info)


def cmd_info(args) -> int:
    from ..motion.gltf import split_animation
    path = args.path
    low = path.lower()
    if low.endswith(".bvh"):
        _info_bvh(path)
    elif low.endswith(".jsonl"):
        from ..motion.stream import read_stream
        _info_take(read_stream(path), "recorded take")
    elif low.endswith(VIDEO_EXTS):
        _info_video(path)
    elif split_animation(path)[0].lower().endswith((".glb", ".gltf", ".vrm", ".vrma")):
        _info_gltf(path)
    else:
        _info_mesh(path)
    return 0


def _info_gltf(ref: str) -> None:
    """A glTF: its mesh (if any), its avatar map when it is skinned, its animations (each usable as
    `--motion FILE#NAME`) and the map of the skeleton they move."""
    import kinetre
    from ..motion.gltf import animation_skeleton, animation_vrm_bones, animations, load_gltf, split_animation
    path, frag = split_animation(ref)
    anims = animations(path)
    try:
        _info_mesh(path)
    except kinetre.BadMeshError:
        if not anims:
            raise
        print(f"{path}: glTF without a mesh")
    _info_avatar(path)
    if not anims:
        print("  animations: none")
        return
    own = load_gltf(path, frag, as_kinect=False).model            # the bones it drives a mesh by
    print(f"  skeleton: {len(own.joints)} joints ({', '.join(own.joints)})")
    print(f"  animations ({len(anims)}), use as --motion {os.path.basename(path)}#NAME or #INDEX:")
    for a in anims:
        print(f"    #{a.index} {a.name}: {a.duration:.2f} s, {a.channels} channels")
    names, parents, rest, tips = animation_skeleton(path, frag)
    _print_motion_map(names, parents, rest, f"--motion {os.path.basename(ref)}", tips, animation_vrm_bones(path, frag))


def _info_avatar(path: str) -> None:
    """The bone map of a rigged file, as `kinetre avatar` uses it (silent for an unrigged one)."""
    from ..avatar.bonemap import auto_map, can_drive, upright_problems
    from ..avatar.load import load_avatar
    from ..errors import BadAvatarError
    try:
        avatar = load_avatar(path)
    except BadAvatarError:
        return
    bonemap = auto_map(avatar)
    problems = upright_problems(bonemap, avatar.bind_positions)
    if problems:
        verdict = f"not an upright humanoid ({'; '.join(problems)}): possess it with kinetre animate"
    elif can_drive(bonemap):
        verdict = f"drivable by kinetre avatar, {len(bonemap.joints)} of 20 joints mapped"
    else:
        verdict = "too little maps to drive it: name the joints in a saved map (kinetre avatar --write-map)"
    print(f"  avatar: {len(avatar.joints)} skin joints; bone map: {verdict}")
    _print_map(bonemap)


def _print_motion_map(names, parents, rest, usage: str, tips: int = 0, vrm: dict | None = None) -> None:
    from ..skeleton.humanoid_map import map_humanoid, not_humanoid
    hmap = map_humanoid(names, parents, rest, vrm=vrm or None, tips=tips)
    why = not_humanoid(hmap, rest)
    if why:
        print(f"  Kinect-20 map: none ({why}): {usage} drives a mesh by its own bones")
        return
    tracked = len(hmap.joints) + len(hmap.derived)
    print(f"  Kinect-20 map: a humanoid, {tracked} of 20 joints tracked ({len(hmap.derived)} derived)")
    _print_map(hmap)


def _print_map(hmap) -> None:
    for line in hmap.describe():
        print(f"    {line}")


def _info_take(take, kind: str) -> None:
    import numpy as np
    first = take.frame(0)
    print(f"{take.source}: {kind}, skeleton {take.model.name} ({len(take.model.joints)} joints), {len(take)} frames "
          f"at {take.fps:g} fps ({take.duration:.2f} s)")
    print(f"  tracked: {100 * take.tracked.mean():.1f} % of joint-frames; first-frame height {first.height:.2f} m")
    lo, hi = np.nanmin(take.positions, axis=(0, 1)), np.nanmax(take.positions, axis=(0, 1))
    print(f"  extent (m): x {lo[0]:.2f}..{hi[0]:.2f}  y {lo[1]:.2f}..{hi[1]:.2f}  z {lo[2]:.2f}..{hi[2]:.2f}")
    print(f"  joints: {', '.join(take.model.joints)}")
    _print_quality(take)
    if kind == "recorded take":
        _print_take_map(take)
    if take.hands is not None:
        _print_hands(take)


def _print_quality(take) -> None:
    """How clean the motion is (kinetre.motion.quality), and what cleaned it when the take records that."""
    from ..motion.quality import take_quality
    print("  quality:")
    for line in take_quality(take).lines():
        print(f"    {line}")
    applied = take.applied or {}
    done = [name for name in ("smoothing", "contact") if name in applied]
    if done:
        lag = (applied.get("smoothing") or {}).get("lag_ms")
        print(f"  cleaned: {' and '.join(done)}" + (f" (lag {lag:.0f} ms)" if lag is not None else ""))


def _print_hands(take) -> None:
    """Each person's hands: in how many frames each is seen, their size, and the hand map `--hand` drives by."""
    import numpy as np

    from ..motion.hands import SIDES, hand_length
    seen = np.isfinite(take.hands).all(axis=(3, 4))  # (T, P, 2)
    print("  hands (--hand left|right [--person ID] drives a mesh by one of them):")
    for k, pid in enumerate(take.people):
        sides = [f"{side} in {int(seen[:, k, i].sum())} frames ({100 * hand_length(take.hands[:, k, i]):.0f} cm)"
                 if seen[:, k, i].any() else f"{side} never" for i, side in enumerate(SIDES)]
        print(f"    person {pid}: {', '.join(sides)}")
    _print_hand_map()


def _print_hand_map() -> None:
    """The hand skeleton: each finger's chain from the wrist, as its bones drive a mesh."""
    from ..skeleton.models import FINGER_JOINTS
    print("  hand map: MediaPipe's 21 hand landmarks, 20 bones; fitted to a mesh from the shapes, fingers as legs")
    for finger, chain in FINGER_JOINTS.items():
        print(f"    {finger}: {' -> '.join(('wrist',) + chain)}")


def _print_take_map(take) -> None:
    """A take on Kinect-20 or OpenNI-17 is a body already; another skeleton is mapped from its first frame."""
    import numpy as np
    name = take.model.name
    if name == "kinect20":
        print("  Kinect-20 map: the take's own joints (Kinect-20)")
    elif name == "hand21":
        _print_hand_map()
    elif name == "openni17":
        print("  Kinect-20 map: from OpenNI-17 by its fixed table; HandLeft, HandRight, FootLeft, FootRight untracked "
              "(OpenNI has no hands and feet)")
    else:
        _print_motion_map(take.model.joints, take.model.parents, np.nan_to_num(take.positions[0]),
                          f"--motion {os.path.basename(take.source or 'take')}")


def _info_bvh(path: str) -> None:
    import numpy as np

    from ..motion.bvh import detect_unit, load_bvh, parse_bvh, rest_positions
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    clip = parse_bvh(text, path)
    per, unit = detect_unit(float(np.ptp(rest_positions(clip), axis=0).max()))
    n_end = int(clip.end_sites.sum())
    print(f"{path}: BVH, {len(clip.names) - n_end} joints + {n_end} end sites, {clip.motion.shape[1]} channels, "
          f"{len(clip.motion)} frames at {clip.fps:g} fps ({(len(clip.motion) - 1) * clip.frame_time:.2f} s)")
    print(f"  unit: {unit} ({per:.4g} m per file unit)")
    _print_motion_map(clip.names, clip.parents, rest_positions(clip) * per, f"--motion {os.path.basename(path)}")
    _info_take(load_bvh(path), "as loaded")


def _info_video(path: str) -> None:
    import cv2
    if not os.path.exists(path):
        raise UsageError(f"{path}: no such file")
    cap = cv2.VideoCapture(path)
    if not cap.isOpened():
        raise UsageError(f"{path}: not a readable video")
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    n, fps = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)), cap.get(cv2.CAP_PROP_FPS)
    cap.release()
    print(f"{path}: video, {w}x{h}, {n} frames at {fps:g} fps ({n / fps if fps else 0:.2f} s); "
          f"`kinetre capture --video` tracks the person in it")


def _info_mesh(path: str) -> None:
    import numpy as np

    import kinetre
    mesh = kinetre.load_mesh(path)
    lo, hi = mesh.bounds
    size = hi - lo
    print(f"{path}: mesh, {len(mesh.vertices)} vertices, {len(mesh.faces)} faces, area {mesh.area:.4g}")
    print(f"  bounding box {size[0]:.4g} x {size[1]:.4g} x {size[2]:.4g} (diagonal {mesh.diagonal:.4g}), "
          f"min {np.round(lo, 4).tolist()}")
    print(f"  UVs: {'yes' if mesh.uvs is not None else 'no'}, vertex colours: "
          f"{'yes' if mesh.colors is not None else 'no'}, material: {'yes' if mesh.material is not None else 'no'}")
