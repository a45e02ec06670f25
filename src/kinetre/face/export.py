"""A reconstructed face (one image or a video's frames) as a textured, animated glTF 2.0 file.

* one mesh on the template's topology; TEXCOORD_0 are the first frame's landmark UVs and its camera frame
  is the embedded texture (glTF UVs cannot be animated portably, so a video's face wears its first frame);
  the material is unlit (KHR_materials_unlit): the photo already carries the lighting;
* morph targets 0-4 are the caricatures (caricature.NAMES, named in `extras.targetNames`), at the weights
  chosen, so a player can dial them afterwards;
* a video adds one morph target per later frame (frame k − frame 0) and one animation whose weights
  channel is one-hot per key with LINEAR interpolation: between two keys the player blends the two
  frames' shapes, which is exactly linear interpolation of vertex positions. Morph-weight animation is
  what three.js, Blender and Babylon all play;
* the tracker's blendshapes, when given, ride along in the mesh's `extras.blendshapes`:
  `{"names": [52 names], "weights": [[52 weights] per frame]}`, row k for frame k (time k / fps, the
  animation's key k). They are data, not morph targets: this mesh's shapes are the rebuilt frames
  themselves (Algorithm 2), it has no ARKit-named targets for them to weigh. three.js puts them in the
  mesh's `userData`; an ARKit-rigged avatar can play them (`kinetre avatar` plays a take's).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pygltflib as gl

from ..errors import ExportError
from ..export.gltf import append_accessor
from .caricature import NAMES, morph_targets
from .reconstruct import CM, FaceFrame
from .template import load_template


def write_face_gltf(path, frames: list[FaceFrame], image: bytes, mime: str, fps: float,
                    caricature: np.ndarray | None = None, name: str = "face",
                    blendshapes: np.ndarray | None = None, blendshape_names: tuple[str, ...] = ()) -> None:
    """Write `frames` (reconstructed without morphs) as .glb/.gltf with `image` (encoded JPEG/PNG bytes);
    `blendshapes` (len(frames), len(blendshape_names)) weights per frame, kept in the mesh's extras."""
    path = Path(path)
    if path.suffix.lower() not in (".glb", ".gltf"):
        raise ExportError(f"{path}: a glTF file must end in .glb or .gltf")
    if not frames:
        raise ExportError(f"{path}: no face frames to write")
    if not fps > 0:
        raise ExportError(f"{path}: fps must be positive, got {fps}")
    caricature = np.zeros(len(NAMES)) if caricature is None else np.asarray(caricature, dtype=float)
    shapes = {}
    if blendshapes is not None:
        blendshapes = np.asarray(blendshapes, dtype=float)
        if blendshapes.shape != (len(frames), len(blendshape_names)) or not np.isfinite(blendshapes).all():
            raise ExportError(f"{path}: blendshapes must be {len(frames)} frames of {len(blendshape_names)} "
                              f"finite weights, got shape {blendshapes.shape}")
        shapes["blendshapes"] = {"names": list(blendshape_names),
                                 "weights": np.round(blendshapes, 4).tolist()}
    template = load_template()
    base = frames[0].vertices.astype(np.float32)
    doc = gl.GLTF2(asset=gl.Asset(generator="kinetre face", version="2.0"), scene=0,
                   scenes=[gl.Scene(nodes=[0])], nodes=[gl.Node(mesh=0, name=name)],
                   extensionsUsed=["KHR_materials_unlit"])
    blob = bytearray()
    vertex = gl.ARRAY_BUFFER
    attrs = gl.Attributes(POSITION=append_accessor(doc, blob, base, gl.VEC3, gl.FLOAT, minmax=True, target=vertex),
                          TEXCOORD_0=append_accessor(doc, blob, frames[0].uvs.astype(np.float32), gl.VEC2, gl.FLOAT,
                                             target=vertex))
    indices = append_accessor(doc, blob, template.triangles.reshape(-1).astype(np.uint16), gl.SCALAR,
                      gl.UNSIGNED_SHORT, target=gl.ELEMENT_ARRAY_BUFFER)
    rotation = frames[0].anchor.rotation @ frames[0].turn
    deltas = [CM * d @ rotation.T for d in morph_targets()] + [f.vertices - frames[0].vertices for f in frames[1:]]
    targets = [{"POSITION": append_accessor(doc, blob, d.astype(np.float32), gl.VEC3, gl.FLOAT, minmax=True,
                                    target=vertex)} for d in deltas]
    extras = {"targetNames": list(NAMES) + [f"frame {k}" for k in range(1, len(frames))], **shapes}
    doc.meshes = [gl.Mesh(name=name, primitives=[gl.Primitive(attributes=attrs, indices=indices, material=0,
                                                              targets=targets)],
                          weights=[float(w) for w in caricature] + [0.0] * (len(frames) - 1),
                          extras=extras)]
    blob.extend(b"\0" * (-len(blob) % 4))
    doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(image)))
    blob.extend(image)
    doc.images = [gl.Image(bufferView=len(doc.bufferViews) - 1, mimeType=mime)]
    doc.samplers = [gl.Sampler(magFilter=gl.LINEAR, minFilter=gl.LINEAR, wrapS=gl.CLAMP_TO_EDGE,
                               wrapT=gl.CLAMP_TO_EDGE)]
    doc.textures = [gl.Texture(source=0, sampler=0)]
    doc.materials = [gl.Material(name=name, doubleSided=True, extensions={"KHR_materials_unlit": {}},
                                 pbrMetallicRoughness=gl.PbrMetallicRoughness(
                                     baseColorTexture=gl.TextureInfo(index=0), metallicFactor=0.0))]
    if len(frames) > 1:
        n = len(frames)
        times = (np.arange(n) / fps).astype(np.float32)
        keys = np.zeros((n, len(NAMES) + n - 1), dtype=np.float32)
        keys[:, : len(NAMES)] = caricature
        keys[np.arange(1, n), len(NAMES) + np.arange(n - 1)] = 1.0
        t_acc = append_accessor(doc, blob, times, gl.SCALAR, gl.FLOAT, minmax=True)
        w_acc = append_accessor(doc, blob, keys.reshape(-1), gl.SCALAR, gl.FLOAT)
        doc.animations = [gl.Animation(name=name, samplers=[gl.AnimationSampler(input=t_acc, output=w_acc,
                                                                                 interpolation="LINEAR")],
                                       channels=[gl.AnimationChannel(sampler=0, target=gl.AnimationChannelTarget(
                                           node=0, path="weights"))])]
    doc.buffers = [gl.Buffer(byteLength=len(blob))]
    doc.set_binary_blob(bytes(blob))
    try:
        if path.suffix.lower() == ".glb":
            doc.save_binary(str(path))
        else:
            doc.convert_buffers(gl.BufferFormat.DATAURI)
            doc.save_json(str(path))
    except OSError as e:
        raise ExportError(f"{path}: cannot write ({e.strerror})") from None
