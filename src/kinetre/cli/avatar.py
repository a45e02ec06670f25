"""`kinetre avatar AVATAR.glb --motion walk.bvh -o out.glb|.gltf|.vrma|.bvh|.mp4|.webm`

Loads a rigged humanoid (glTF/GLB/VRM), maps its bones to Kinect-20 (a saved map next to it wins), retargets
any motion source (BVH, recorded take, video) with Algorithm 1 and writes the avatar animated by its own
joints, the take alone as a VRM Animation (.vrma, with VRM expressions from the take's face), or streams it
live to a VMC receiver (`--vmc HOST:PORT`, vmc/send.py). `--write-map` saves the automatic map as JSON next
to the avatar for hand correction.
"""
from __future__ import annotations

import os
import time

from .common import (VIDEO_EXTS, UsageError, add_cleanup_options, cleaned, frame_range, load_motion, output_ext,
                     prepare_mediapipe, write_report)

OUTPUTS = (".glb", ".gltf", ".fbx", ".vrma", ".bvh", ".mp4", ".webm")


def register(sub) -> None:
    """Add `kinetre avatar` to the `kinetre` parser's subcommands."""
    p = sub.add_parser(
        "avatar", help="drive a rigged humanoid avatar (glTF/GLB/VRM) by its own bones with a motion",
        description="Retarget a motion onto a rigged humanoid avatar (avateering, Algorithm 1) and write it "
                    "animated by its own skeleton.")
    p.add_argument("avatar", help="rigged humanoid: .glb, .gltf or .vrm")
    p.add_argument("--motion", help="motion: .bvh, .kinetre.jsonl or a video")
    p.add_argument("--person", type=int, default=None, metavar="ID",
                   help="a camera take's person to follow, by id (default: the main person)")
    p.add_argument("-o", "--output", help=f"output: {' '.join(OUTPUTS)}")
    p.add_argument("--vmc", default=None, metavar="HOST:PORT",
                   help="stream the take in real time to a VMC receiver (VSeeFace, Warudo...; port 39539 by "
                        "default) instead of writing a file")
    p.add_argument("--map", default=None, metavar="JSON",
                   help="bone map to use (default: AVATAR.kinetre-map.json next to the avatar when present)")
    p.add_argument("--write-map", nargs="?", const="", default=None, metavar="JSON",
                   help="save the bone map (default: next to the avatar) for hand correction")
    p.add_argument("--scale", type=float, default=None, help="BVH: metres per file unit (default: guessed)")
    p.add_argument("--fps", type=float, default=None, help="output frame rate (default: the take's, at most 30)")
    p.add_argument("--frames", default=None, metavar="START:END", help="use only these frames of the take")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many output frames")
    add_cleanup_options(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no summary")
    p.set_defaults(func=cmd_avatar)


def cmd_avatar(args) -> int:
    from ..motion.source import resample
    from ..avatar.bonemap import describe, kinect_take, map_bones, map_path, write_map
    from ..avatar.drive import hands_and_face
    from ..avatar.load import load_avatar
    from ..avatar.own_motion import own_joints, own_motion
    from ..avatar.retarget import plan_retarget, retarget

    say = (lambda *a: None) if args.quiet else print
    t0 = time.perf_counter()
    if args.motion is None and args.write_map is None:
        raise UsageError("kinetre avatar needs --motion (and -o), or --write-map")
    if args.motion is not None and not args.output and args.vmc is None:
        raise UsageError("kinetre avatar --motion needs -o OUTPUT or --vmc HOST:PORT")
    if args.vmc is not None and args.output:
        raise UsageError("kinetre avatar: --vmc streams the take instead of writing it; give -o or --vmc")
    out_ext = output_ext(args.output, OUTPUTS) if args.output else None
    if out_ext == ".fbx":
        from ..blender.fbx import check_fbx
        check_fbx(args.output)  # before any work: FBX needs Blender
    if args.map is not None and not os.path.exists(args.map):
        raise UsageError(f"{args.map}: no such bone map")
    avatar = load_avatar(args.avatar)
    bonemap = map_bones(avatar, args.map)
    say(f"avatar {args.avatar}: {len(avatar.joints)} joints, {avatar.vertex_count} vertices in "
        f"{len(avatar.primitives)} primitive(s)")
    say(f"bone map: {describe(avatar, bonemap)}")
    if args.write_map is not None:
        target = args.write_map or map_path(args.avatar)
        write_map(target, avatar, bonemap.joints)
        say(f"wrote {target}")
    if args.motion is None:
        return 0

    if args.motion.lower().endswith(VIDEO_EXTS):
        prepare_mediapipe()
    loaded = load_motion(args.motion, args.scale)
    # the avatar's own animation plays as its artist made it; any other motion is retargeted through Kinect-20
    own = args.vmc is None and args.person is None and \
        own_joints(avatar, loaded.native if loaded.native is not None else loaded) is not None
    take = loaded if own else kinect_take(loaded)
    if args.person is not None:
        take = take.person(args.person)
    frames = frame_range(args.frames)
    take = take.slice(frames.start or 0, frames.stop)
    take = resample(take, args.fps if args.fps is not None else min(take.fps, 30.0))
    if args.max_frames is not None:
        take = take.slice(0, max(1, args.max_frames))
    before = take
    take = cleaned(take, args, say)
    plan = plan_retarget(avatar, bonemap)
    motion = own_motion(avatar, take) if own else None
    if motion is None:
        take = kinect_take(take)
        motion = retarget(plan, take.positions, take.tracked, root_turns=take.hips_turns)
    else:
        say(f"{args.motion} is on the avatar's own skeleton: played as it is")
    motion, morphs = hands_and_face(avatar, bonemap, plan, motion, take, say)
    if args.report:
        write_report(args.report, _report(args, before, take, avatar, bonemap, motion))
        say(f"wrote {args.report}")
    if args.vmc is not None:
        from ..avatar.fingers import map_fingers
        from ..vmc.send import VmcSender, blend_frames, parse_address, vmc_frames
        host, port = parse_address(args.vmc)
        frames = vmc_frames(plan, bonemap, motion, map_fingers(avatar, bonemap) if take.hands is not None else None)
        faces = take.main_blendshapes()
        blend = None if faces is None else blend_frames(take.blendshape_names, faces)
        sender = VmcSender(host, port)
        say(f"streaming {len(take)} frames at {take.fps:g} fps to VMC {host}:{port} ({len(frames.bones)} bones"
            f"{'' if blend is None else f', {len(blend[0])} blendshapes'})")
        try:
            sender.stream(frames, take.fps, blend)
        finally:
            sender.close()
        say(f"sent {sender.sent} VMC frames from {args.motion} ({time.perf_counter() - t0:.1f} s)")
        return 0
    if out_ext in (".glb", ".gltf", ".fbx"):
        from ..avatar.export import write_avatar_gltf
        from ..blender.fbx import gltf_or_fbx
        with gltf_or_fbx(args.output, take.fps) as path:  # FBX: Blender converts the glTF
            write_avatar_gltf(path, avatar, motion, take.fps, morph_weights=morphs)
    elif out_ext == ".vrma":
        from ..avatar.expressions import vrm_expressions
        from ..avatar.normalized import normalized_motion
        from ..avatar.vrma import write_vrma
        faces = take.main_blendshapes()
        expressions = None if faces is None else vrm_expressions(take.blendshape_names, faces)
        write_vrma(args.output, normalized_motion(plan, bonemap, motion), take.fps, expressions)
        if expressions is not None:
            say(f"VRM expressions: {len(expressions[0])} presets, {len(expressions[1])} custom")
    elif out_ext == ".bvh":
        from ..avatar.export import write_avatar_bvh
        write_avatar_bvh(args.output, avatar, plan, motion, take.fps)
    else:
        from ..avatar.export import write_avatar_video
        write_avatar_video(args.output, avatar, motion, take.fps)
    say(f"wrote {args.output} ({len(take)} frames at {take.fps:g} fps from {args.motion}, "
        f"{time.perf_counter() - t0:.1f} s)")
    return 0


def _report(args, before, take, avatar, bonemap, motion) -> dict:
    """The quality of the driving take (as loaded and as cleaned) and of the avatar's own feet."""
    from ..motion.quality import measure, take_quality
    report = {"motion": args.motion, "output": args.output or args.vmc, "applied": take.applied,
              "take": take_quality(take).to_dict()}
    if take is not before:
        report["take_as_tracked"] = take_quality(before).to_dict()
    feet = [(name, bonemap.joints.get(name, bonemap.joints.get(ankle)))
            for name, ankle in (("FootLeft", "AnkleLeft"), ("FootRight", "AnkleRight"))]
    feet = [(name, j) for name, j in feet if j is not None]
    if feet:
        report["avatar_feet"] = measure(motion.positions, take.fps, tuple(j for _, j in feet),
                                        tuple(avatar.joint_names[j] for _, j in feet)).to_dict()
    return report
