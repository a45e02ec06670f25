"""A small rigged humanoid written with pygltflib for the hand and face tests: Mixamo-named bones with
four-joint fingers on both hands, one box of vertices rigid on each joint, and ARKit-named morph targets
(`extras.targetNames`) that move the head box. None of the shared avatars has both fingers and morphs."""
from __future__ import annotations

import numpy as np
import pygltflib as gl

MORPHS = ("jawOpen", "eyeBlinkLeft", "mouthSmileRight")
FINGER_NAMES = ("Thumb", "Index", "Middle", "Ring", "Pinky")


def skeleton() -> tuple[list[str], list[int], np.ndarray]:
    """Joint names, parents and bind positions (metres, +Y up, facing +Z, the avatar's left on +X)."""
    names, parents, pos = [], [], []

    def add(name, parent, p):
        names.append(name)
        parents.append(names.index(parent) if parent else -1)
        pos.append(p)
    add("Hips", None, (0, 1.0, 0))
    add("Spine", "Hips", (0, 1.15, 0))
    add("Spine1", "Spine", (0, 1.3, 0))
    add("Neck", "Spine1", (0, 1.5, 0))
    add("Head", "Neck", (0, 1.6, 0))
    add("HeadTop_End", "Head", (0, 1.8, 0))
    for side, x in (("Left", 1.0), ("Right", -1.0)):
        add(f"{side}Shoulder", "Spine1", (0.05 * x, 1.45, 0))
        add(f"{side}Arm", f"{side}Shoulder", (0.15 * x, 1.45, 0))
        add(f"{side}ForeArm", f"{side}Arm", (0.42 * x, 1.45, 0))
        add(f"{side}Hand", f"{side}ForeArm", (0.67 * x, 1.45, 0))
        for f, z in zip(FINGER_NAMES, (0.05, 0.025, 0.0, -0.02, -0.04)):
            start = 0.70 if f == "Thumb" else 0.75
            for k in range(4):
                parent = f"{side}Hand" if k == 0 else f"{side}Hand{f}{k}"
                add(f"{side}Hand{f}{k + 1}", parent,
                    ((start + 0.03 * k) * x, 1.45 - (0.01 * k if f == "Thumb" else 0.0), z + (0.015 * k if f == "Thumb" else 0.0)))
        add(f"{side}UpLeg", "Hips", (0.1 * x, 0.95, 0))
        add(f"{side}Leg", f"{side}UpLeg", (0.1 * x, 0.5, 0))
        add(f"{side}Foot", f"{side}Leg", (0.1 * x, 0.08, 0))
        add(f"{side}ToeBase", f"{side}Foot", (0.1 * x, 0.02, 0.12))
    return [f"mixamorig:{n}" for n in names], parents, np.array(pos, dtype=np.float64)


def write_rigged_avatar(path, morphs: tuple[str, ...] = MORPHS) -> None:
    names, parents, pos = skeleton()
    n = len(names)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64) * 0.01
    box_faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                          [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    verts = np.concatenate([pos[j] + corners for j in range(n)]).astype(np.float32)
    faces = np.concatenate([box_faces + 8 * j for j in range(n)]).astype(np.uint16)
    joints = np.repeat(np.arange(n), 8)[:, None] * np.array([[1, 0, 0, 0]])
    weights = np.tile([1.0, 0.0, 0.0, 0.0], (len(verts), 1)).astype(np.float32)
    head = names.index("mixamorig:Head")
    deltas = []
    for k in range(len(morphs)):
        d = np.zeros_like(verts)
        d[8 * head:8 * head + 8, 1] = -0.02 * (k + 1)
        deltas.append(d)

    blob = bytearray()
    doc = gl.GLTF2(asset=gl.Asset(version="2.0"), scene=0, buffers=[], bufferViews=[], accessors=[])

    def accessor(array, kind, component, minmax=False):
        blob.extend(b"\0" * (-len(blob) % 4))
        data = np.ascontiguousarray(array)
        doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=data.nbytes))
        blob.extend(data.tobytes())
        acc = gl.Accessor(bufferView=len(doc.bufferViews) - 1, componentType=component, count=len(array), type=kind)
        if minmax:
            acc.min, acc.max = data.min(axis=0).tolist(), data.max(axis=0).tolist()
        doc.accessors.append(acc)
        return len(doc.accessors) - 1

    attrs = gl.Attributes(POSITION=accessor(verts, gl.VEC3, gl.FLOAT, True),
                          JOINTS_0=accessor(joints.astype(np.uint8), gl.VEC4, gl.UNSIGNED_BYTE),
                          WEIGHTS_0=accessor(weights, gl.VEC4, gl.FLOAT))
    targets = [{"POSITION": accessor(d, gl.VEC3, gl.FLOAT, True)} for d in deltas]
    prim = gl.Primitive(attributes=attrs, indices=accessor(faces.reshape(-1), gl.SCALAR, gl.UNSIGNED_SHORT),
                        targets=targets or None)
    doc.meshes = [gl.Mesh(name="body", primitives=[prim], weights=[0.0] * len(morphs) or None,
                          extras={"targetNames": list(morphs)})]
    ibm = np.stack([np.linalg.inv(np.block([[np.eye(3), pos[j][:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
                    for j in range(n)])
    doc.skins = [gl.Skin(joints=list(range(n)), inverseBindMatrices=accessor(
        ibm.transpose(0, 2, 1).reshape(n, 16).astype(np.float32), gl.MAT4, gl.FLOAT))]
    doc.nodes = []
    for j in range(n):
        offset = pos[j] - (pos[parents[j]] if parents[j] >= 0 else 0.0)
        children = [c for c in range(n) if parents[c] == j]
        doc.nodes.append(gl.Node(name=names[j], translation=offset.tolist(), children=children or None))
    doc.nodes.append(gl.Node(name="body", mesh=0, skin=0))
    doc.scenes = [gl.Scene(nodes=[0, n])]
    doc.buffers = [gl.Buffer(byteLength=len(blob))]
    doc.set_binary_blob(bytes(blob))
    doc.save_binary(str(path))
