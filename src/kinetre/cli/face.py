"""`kinetre face IMAGE|VIDEO -o face.glb`: the reconstructed face (Algorithm 2) as a textured glTF."""
from __future__ import annotations

import os

from ..errors import BadFaceError, KinetreError
from ..face.caricature import NAMES, PRESETS, weights_from
from .common import prepare_mediapipe


def _caricature(args):
    values = dict(PRESETS[args.preset]) if args.preset else {}
    for item in args.morph or []:
        name, _, value = item.partition("=")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            raise BadFaceError(f"--morph {item!r}: expected NAME=WEIGHT, e.g. eyes=0.8") from None
    try:
        return weights_from(values)
    except ValueError as e:
        raise BadFaceError(f"--morph: {e}") from None


def cmd_face(args) -> int:
    from ..face.export import write_face_gltf
    from ..face.pipeline import face_take

    if not args.output.lower().endswith((".glb", ".gltf")):
        raise KinetreError(f"{args.output}: the face is written as glTF: use .glb or .gltf")
    caricature = _caricature(args)
    if args.landmarks is None:  # tracked by FaceLandmarker, not read from a file
        prepare_mediapipe()
    else:
        os.environ.setdefault("GLOG_minloglevel", "2")
    take = face_take(args.input, args.landmarks, max_frames=args.max_frames, turn=args.turn)
    write_face_gltf(args.output, take.frames, take.image, take.mime, take.fps, caricature,
                    blendshapes=take.blendshapes, blendshape_names=take.blendshape_names)
    shapes = f", {len(take.blendshape_names)} blendshapes a frame" if take.blendshapes is not None else ""
    print(f"wrote {args.output}: {len(take.frames)} frame(s) at {take.fps:g} fps, a face in {take.tracked}"
          f"{shapes}")
    return 0


def register(sub) -> None:
    """Add `kinetre face` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("face", help="rebuild a textured 3D face from a photo or a video (animated)",
                       description=__doc__)
    p.add_argument("input", help="image (.jpg, .png, ...) or video")
    p.add_argument("-o", "--output", required=True, help=".glb or .gltf")
    p.add_argument("--landmarks", help="landmark file (JSON from the studio's /annotate page) for an image "
                                       "the tracker misses")
    p.add_argument("--preset", choices=sorted(PRESETS), help="caricature preset (morph weights)")
    p.add_argument("--morph", action="append", metavar="NAME=WEIGHT",
                   help=f"caricature morph weight, repeatable; NAME in {', '.join(NAMES)}")
    p.add_argument("--turn", action="store_true",
                   help="turn the face with the tracked head (default: frontal, as on an avatar's neck)")
    p.add_argument("--max-frames", type=int, default=None, help="read at most this many video frames")
    p.set_defaults(func=cmd_face)
