"""A retargeted take as a VRM Animation (.vrma): glTF 2.0 with the `VRMC_vrm_animation` 1.0 extension.

The file holds no mesh, only the normalised humanoid (avatar/normalized.py): one node per humanoid bone,
in the T-pose with identity rotations, hung as VRM's humanoid hierarchy (hips at the root), and one
animation with a rotation track per bone and a translation track for the hips, keyed at every frame. The
extension maps VRM bone names to those nodes, so any VRM 1.0 (or 0.x) avatar plays it on its own bones.
With face weights, each VRM expression is one more node whose translation.x carries the weight
(`expressions.preset` / `expressions.custom`, as the extension specifies).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pygltflib as gl

from ..errors import ExportError
from ..export.gltf import append_accessor, rotation_quaternions, save_gltf
from .normalized import NormalizedMotion, vrm_name

EXTENSION = "VRMC_vrm_animation"


def write_vrma(path, motion: NormalizedMotion, fps: float, expressions: tuple[dict, dict] | None = None,
               name: str = "take") -> None:
    """Write `motion` (and `expressions`: ({preset: (T,)}, {custom: (T,)}) weights) as a .vrma file.

    Raises
    ------
    ExportError
        Bad extension, empty or non-finite motion or weights, unwritable path.
    """
    path = Path(path)
    if path.suffix.lower() != ".vrma":
        raise ExportError(f"{path}: a VRM Animation file must end in .vrma, got {path.suffix or 'no extension'!r}")
    t = len(motion)
    if not t:
        raise ExportError(f"{path}: the take has no frames to export")
    if not (np.isfinite(fps) and fps > 0):
        raise ExportError(f"{path}: fps must be a positive number, got {fps}")
    if not (np.isfinite(motion.rotations).all() and np.isfinite(motion.hips).all()):
        raise ExportError(f"{path}: the retargeted motion is not finite")
    preset, custom = expressions or ({}, {})
    for label, w in {**preset, **custom}.items():
        if np.shape(w) != (t,) or not np.isfinite(w).all():
            raise ExportError(f"{path}: expression {label!r} needs {t} finite weights")

    doc = gl.GLTF2(nodes=[], bufferViews=[], accessors=[], scenes=[gl.Scene(nodes=[0])], scene=0)
    blob = bytearray()
    bones = motion.bones
    for k, bone in enumerate(bones):
        doc.nodes.append(gl.Node(name=vrm_name(bone), translation=[float(x) for x in motion.rest[k]]))
    for k in range(len(bones)):
        p = motion.parent(k)
        if p >= 0:
            doc.nodes[p].children = (doc.nodes[p].children or []) + [k]
    times = append_accessor(doc, blob, (np.arange(t) / fps).astype(np.float32), gl.SCALAR, gl.FLOAT, minmax=True)
    samplers, channels = [], []

    def track(node, prop, values, kind):
        acc = append_accessor(doc, blob, np.ascontiguousarray(values, dtype=np.float32), kind, gl.FLOAT)
        samplers.append(gl.AnimationSampler(input=times, output=acc, interpolation="LINEAR"))
        channels.append(gl.AnimationChannel(sampler=len(samplers) - 1,
                                            target=gl.AnimationChannelTarget(node=node, path=prop)))

    quats = rotation_quaternions(motion.rotations)
    track(0, "translation", motion.hips, gl.VEC3)
    for k in range(len(bones)):
        track(k, "rotation", quats[:, k], gl.VEC4)
    extension = {"specVersion": "1.0",
                 "humanoid": {"humanBones": {vrm_name(b): {"node": k} for k, b in enumerate(bones)}}}
    groups = {}
    for group, weights in (("preset", preset), ("custom", custom)):
        for label, w in weights.items():
            node = len(doc.nodes)
            doc.nodes.append(gl.Node(name=f"expression.{label}", translation=[0.0, 0.0, 0.0]))
            doc.scenes[0].nodes.append(node)
            groups.setdefault(group, {})[label] = {"node": node}
            track(node, "translation", np.stack([w, np.zeros(t), np.zeros(t)], axis=1), gl.VEC3)
    if groups:
        extension["expressions"] = groups
    doc.animations = [gl.Animation(name=name, samplers=samplers, channels=channels)]
    doc.extensionsUsed = [EXTENSION]
    doc.extensions = {EXTENSION: extension}
    save_gltf(path, doc, blob, "Kinetre (avatar retargeting, VRM Animation)", binary=True)
