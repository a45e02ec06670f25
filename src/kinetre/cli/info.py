"""`kinetre info FILE`: what a mesh, glTF, BVH, take or video holds, and how the other commands can use it."""
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
    elif split_animation(path)[0].lower().endswith((".glb", ".gltf")):
        _info_gltf(split_animation(path)[0])
    else:
        _info_mesh(path)
    return 0


def _info_gltf(path: str) -> None:
    """A glTF: its mesh (if any) and its animations, each usable as `--motion FILE#NAME`."""
    import kinetre
    from ..motion.gltf import animations, load_gltf
    anims = animations(path)
    try:
        _info_mesh(path)
    except kinetre.BadMeshError:
        if not anims:
            raise
        print(f"{path}: glTF without a mesh")
    if not anims:
        print("  animations: none")
        return
    take = load_gltf(path, 0, as_kinect=False)
    print(f"  skeleton: {len(take.model.joints)} joints ({', '.join(take.model.joints)})")
    print(f"  animations ({len(anims)}), use as --motion {os.path.basename(path)}#NAME or #INDEX:")
    for a in anims:
        print(f"    #{a.index} {a.name}: {a.duration:.2f} s, {a.channels} channels")


def _info_take(take, kind: str) -> None:
    import numpy as np
    first = take.frame(0)
    print(f"{take.source}: {kind}, skeleton {take.model.name} ({len(take.model.joints)} joints), {len(take)} frames "
          f"at {take.fps:g} fps ({take.duration:.2f} s)")
    print(f"  tracked: {100 * take.tracked.mean():.1f} % of joint-frames; first-frame height {first.height:.2f} m")
    lo, hi = np.nanmin(take.positions, axis=(0, 1)), np.nanmax(take.positions, axis=(0, 1))
    print(f"  extent (m): x {lo[0]:.2f}..{hi[0]:.2f}  y {lo[1]:.2f}..{hi[1]:.2f}  z {lo[2]:.2f}..{hi[2]:.2f}")
    print(f"  joints: {', '.join(take.model.joints)}")


def _info_bvh(path: str) -> None:
    import numpy as np

    from ..motion.bvh import detect_unit, kinect_map, load_bvh, parse_bvh, rest_positions
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
    mapping = kinect_map(clip.names, clip.parents)
    if mapping is None:
        print("  Kinect-20 map: no (core joints not found by name): drives a mesh by its own bones")
    else:
        print("  Kinect-20 map: " + ", ".join(f"{k}<-{v}" for k, v in mapping[1].items()))
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
