"""Small valid files of every kind the readers take, for the fuzz tests to break: made here from trimesh
shapes, the shared test data and Kinetre's own writers, so every seed reads cleanly before it is mutated."""
from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data"
# files kept because making them takes long: walk.vrma is `kinetre avatar RiggedFigure.glb --motion` on the
# first four frames of short_bvh(), written as a VRM Animation
KEPT = Path(__file__).resolve().parent / "seeds"


def _shape():
    import trimesh
    return trimesh.creation.icosphere(subdivisions=1, radius=0.5)  # 42 vertices, 80 faces


def binary_ply(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """Little-endian PLY, float32 x, y, z and uchar-counted int32 triangles (the layout ply_mutation knows)."""
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\nproperty float x\n"
              f"property float y\nproperty float z\nelement face {len(faces)}\n"
              "property list uchar int vertex_indices\nend_header\n").encode()
    body = np.ascontiguousarray(vertices, "<f4").tobytes()
    body += b"".join(struct.pack("<B3i", 3, *map(int, f)) for f in faces)
    return header + body


def mesh_seeds() -> dict[str, bytes]:
    """name -> bytes of one small mesh in each format the mesh reader takes."""
    tm = _shape()
    out = {"shape.ply": binary_ply(tm.vertices, tm.faces)}
    for name, kind in (("shape.obj", "obj"), ("shape.off", "off"), ("shape.stl", "stl"), ("ascii.stl", "stl_ascii"),
                       ("ascii.ply", "ply"), ("shape.glb", "glb")):
        kwargs = {"encoding": "ascii"} if name == "ascii.ply" else {}
        data = tm.export(file_type=kind, **kwargs)
        out[name] = data.encode() if isinstance(data, str) else bytes(data)
    return out


def _with_vrm(glb: bytes, version: int) -> bytes:
    """A GLB with VRM 0.x or 1.0 humanoid bones naming its first skin's joints."""
    from fuzz.mutate import glb_bytes, glb_parts
    doc, blob = glb_parts(glb)
    joints = doc["skins"][0]["joints"]
    names = ("hips", "spine", "chest", "neck", "head", "leftUpperArm", "leftLowerArm", "leftHand",
             "rightUpperArm", "rightLowerArm", "rightHand", "leftUpperLeg", "leftLowerLeg", "leftFoot",
             "rightUpperLeg", "rightLowerLeg", "rightFoot")
    pairs = list(zip(names, joints))
    if version == 0:
        doc.setdefault("extensions", {})["VRM"] = {
            "humanoid": {"humanBones": [{"bone": b, "node": n} for b, n in pairs]}}
    else:
        doc.setdefault("extensions", {})["VRMC_vrm"] = {
            "specVersion": "1.0", "humanoid": {"humanBones": {b: {"node": n} for b, n in pairs}}}
    return glb_bytes(doc, blob)


def short_bvh(frames: int = 8) -> bytes:
    """A real BVH (the shared pybvh test clip) cut to its first frames."""
    text = (DATA / "bvh" / "pybvh_test1.bvh").read_bytes()
    head, motion = text.split(b"MOTION", 1)
    lines = motion.strip().splitlines()
    rows = [ln for ln in lines[2:] if ln.strip()][:frames]
    return head + b"MOTION\nFrames: %d\n" % frames + lines[1] + b"\n" + b"\n".join(rows) + b"\n"


def gltf_seeds(tmp: Path) -> dict[str, bytes]:
    """name -> bytes: rigged and animated GLBs (a real one and the avatar tests' synthetic one), VRM 0.x and
    1.0, a VRM Animation written by `kinetre avatar`, and a .gltf with its buffer in a data URI."""
    import base64

    from avatar.synthetic import write_rigged_avatar
    rigged = (DATA / "avatars" / "RiggedFigure.glb").read_bytes()
    write_rigged_avatar(tmp / "synthetic.glb")
    from fuzz.mutate import glb_parts
    doc, blob = glb_parts(rigged)
    doc["buffers"] = [{"byteLength": len(blob),
                       "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}]
    return {"rigged.glb": rigged, "synthetic.glb": (tmp / "synthetic.glb").read_bytes(),
            "vrm0.vrm": _with_vrm(rigged, 0), "vrm1.vrm": _with_vrm(rigged, 1),
            # no reader takes .vrma by name: its content is read as the glTF motion it is
            "vrma.glb": (KEPT / "walk.vrma").read_bytes(),
            "embedded.gltf": json.dumps(doc).encode()}


def take_seeds(tmp: Path) -> dict[str, bytes]:
    """name -> bytes: a Kinect-20 take recorded from a BVH, and a two-person take with hands and a face."""
    from kinetre.motion.bvh import load_bvh
    from kinetre.motion.stream import write_stream
    from kinetre.motion.take import PersonFrame, crowd_take
    from kinetre.skeleton.mediapipe import BLENDSHAPES
    bvh = tmp / "short.bvh"
    bvh.write_bytes(short_bvh(6))
    take = load_bvh(bvh)
    write_stream(tmp / "body.kinetre.jsonl", take)
    frames = take.frames()
    rng = np.random.default_rng(0)
    people = [tuple(PersonFrame(pid, f, rng.normal(size=(2, 21, 3)) * 0.05, rng.uniform(size=len(BLENDSHAPES)))
                    for pid in (1, 2)) for f in frames]
    write_stream(tmp / "people.kinetre.jsonl", crowd_take(frames, people, take.fps, "two", tuple(BLENDSHAPES)))
    return {name: (tmp / name).read_bytes() for name in ("body.kinetre.jsonl", "people.kinetre.jsonl")}


def _png(array: np.ndarray) -> bytes:
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(array).save(buf, format="PNG")
    return buf.getvalue()


INTRINSICS = {"width": 40, "height": 30, "intrinsic_matrix": [36.0, 0, 0, 0, 36.0, 0, 19.5, 14.5, 1]}


def rgbd_seed() -> dict[str, bytes]:
    """A Redwood-layout folder of three 40x30 frames looking at a box on a floor, with its intrinsics."""
    files = {"intrinsics.json": json.dumps(INTRINSICS).encode()}
    v, u = np.mgrid[0:30, 0:40]
    for i in range(3):
        depth = np.full((30, 40), 1500 + 10 * i, np.uint16)
        depth[v > 20] = 1200
        depth[8:18, 12 + i:26 + i] = 900
        color = np.stack([(u * 6) % 256, (v * 8) % 256, np.full_like(u, 90 + 40 * i)], axis=-1).astype(np.uint8)
        files[f"depth/{i:05d}.png"] = _png(depth)
        files[f"color/{i:05d}.png"] = _png(color)
    return files


def messages() -> list[dict]:
    """One well-formed message of each kind a studio client sends (studio/protocol.py)."""
    from kinetre.skeleton.models import KINECT20
    rng = np.random.default_rng(1)
    positions = (rng.normal(size=(len(KINECT20.joints), 3)) * 0.3 + [0, 1, 2]).round(4).tolist()
    hands = [(rng.normal(size=(21, 3)) * 0.05).round(4).tolist(), None]
    return [
        {"type": "skeleton", "seq": 3, "t": 100.0, "model": "kinect20", "positions": positions,
         "tracked": [True] * len(positions), "hands": hands, "blendshapes": [0.1] * 52, "person": 2},
        {"type": "possess", "subset": ["left arm", "right leg"], "hand": None, "mesh": 1},
        {"type": "release", "person": 1}, {"type": "subset", "subset": "arms"},
        {"type": "place", "scale": 1.0, "position": [0.0, 0.0, 0.0], "yaw": 0.5, "mesh": 1},
        {"type": "fit", "mesh": 1}, {"type": "player", "on": True}, {"type": "stats"},
        {"type": "subscribe", "skeletons": True, "window": 8}, {"type": "ack", "received": 12},
    ]
