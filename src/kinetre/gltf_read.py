"""Reading glTF 2.0 files, once for every stage (motion from animations, rigged avatars): the document with
its buffers (GLB chunk, data URIs, files next to it) and accessors decoded as glTF 2.0 §3.6 says (byteStride,
normalized integers, sparse substitution).

Every failure raises the error class the caller names (BadMotionError, BadAvatarError), naming the file.
"""
from __future__ import annotations

import base64
import math
import os
from pathlib import Path

import numpy as np

COMPONENT_TYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
                   5126: np.float32}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
# an accessor without a buffer view is zeros (glTF 2.0 §3.6.2.3): its size is not bounded by the file's
MAX_ZERO_ELEMENTS = 1 << 26


def _index(value, size: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < size


def _count(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _numbers(value, length: int) -> bool:
    return (isinstance(value, (list, tuple)) and len(value) == length and
            all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value))


def document_problem(doc) -> str | None:
    """The first broken reference or value in a glTF document, as a phrase, or None when every index points
    at an existing object, counts and offsets are non-negative integers and node transforms are finite
    (glTF 2.0 §3.5: nodes form disjoint strict trees). Readers index by these without further checks."""
    lists = {}
    for name in ("nodes", "meshes", "skins", "accessors", "bufferViews", "buffers", "materials", "textures",
                 "images", "scenes", "animations", "cameras", "samplers"):
        value = getattr(doc, name, None)
        if value is None:
            value = []
        if not isinstance(value, list):
            return f"'{name}' is not a list"
        lists[name] = value
    size = {name: len(v) for name, v in lists.items()}

    def ref(value, kind, optional=True):
        return (optional and value is None) or _index(value, size[kind])

    if not ref(doc.scene, "scenes"):
        return f"scene {doc.scene!r} does not exist"
    for i, scene in enumerate(lists["scenes"]):
        if not all(ref(n, "nodes", False) for n in scene.nodes or []):
            return f"scene {i} names a node that does not exist"
    parent = {}
    for i, node in enumerate(lists["nodes"]):
        children = node.children or []
        if not isinstance(children, list):
            return f"node {i} has children that are not a list"
        for c in children:
            if not ref(c, "nodes", False) or c == i or c in parent:
                return f"node {i} has a bad or shared child {c!r}"
            parent[c] = i
        if not (ref(node.mesh, "meshes") and ref(node.skin, "skins") and ref(node.camera, "cameras")):
            return f"node {i} names a mesh, skin or camera that does not exist"
        if node.matrix is not None and not _numbers(node.matrix, 16):
            return f"node {i} has a matrix that is not 16 finite numbers"
        for field, length in (("translation", 3), ("rotation", 4), ("scale", 3)):
            value = getattr(node, field)
            if value is not None and not _numbers(value, length):
                return f"node {i} has a {field} that is not {length} finite numbers"
    for i in range(size["nodes"]):  # a cycle: walking up from a node comes back to it
        seen, p = {i}, parent.get(i)
        while p is not None:
            if p in seen:
                return f"the node hierarchy has a cycle through node {i}"
            seen.add(p)
            p = parent.get(p)
    for i, skin in enumerate(lists["skins"]):
        joints = skin.joints or []
        if not isinstance(joints, list) or not all(ref(j, "nodes", False) for j in joints) or \
                not ref(skin.inverseBindMatrices, "accessors") or not ref(skin.skeleton, "nodes"):
            return f"skin {i} names a node or accessor that does not exist"
    for i, mesh in enumerate(lists["meshes"]):
        primitives = mesh.primitives or []
        if not isinstance(primitives, list):
            return f"mesh {i} has primitives that are not a list"
        for k, prim in enumerate(primitives):
            attrs = prim.attributes
            values = list(vars(attrs).values()) if attrs is not None and hasattr(attrs, "__dict__") else []
            for target in prim.targets or []:
                values += list(target.values()) if isinstance(target, dict) else [target]
            if not all(ref(a, "accessors") for a in values) or not ref(prim.indices, "accessors") or \
                    not ref(prim.material, "materials") or not (prim.mode is None or _index(prim.mode, 7)):
                return f"mesh {i} primitive {k} names an accessor or material that does not exist"
    for i, a in enumerate(lists["accessors"]):
        if a.componentType not in COMPONENT_TYPES or a.type not in WIDTHS or not _count(a.count) or \
                not (a.byteOffset is None or _count(a.byteOffset)) or not ref(a.bufferView, "bufferViews"):
            return f"accessor {i} has a bad type, count, offset or buffer view"
        if a.bufferView is None and a.count * WIDTHS[a.type] > MAX_ZERO_ELEMENTS:
            return f"accessor {i} has {a.count} elements and no data"
        s = a.sparse
        if s is not None:
            if not _count(s.count) or s.count > a.count or s.indices is None or s.values is None or \
                    s.indices.componentType not in COMPONENT_TYPES or \
                    not ref(s.indices.bufferView, "bufferViews", False) or \
                    not ref(s.values.bufferView, "bufferViews", False) or \
                    not all(o is None or _count(o) for o in (s.indices.byteOffset, s.values.byteOffset)):
                return f"accessor {i} has a malformed sparse part"
    for i, bv in enumerate(lists["bufferViews"]):
        stride = bv.byteStride
        if not ref(bv.buffer, "buffers", False) or not _count(bv.byteLength) or \
                not (bv.byteOffset is None or _count(bv.byteOffset)) or \
                not (stride is None or (_count(stride) and 4 <= stride <= 252)):
            return f"buffer view {i} has a bad buffer, offset, length or stride"
    for i, buf in enumerate(lists["buffers"]):
        if not (buf.byteLength is None or _count(buf.byteLength)) or not (buf.uri is None or isinstance(buf.uri, str)):
            return f"buffer {i} has a bad byteLength or uri"
    for i, anim in enumerate(lists["animations"]):
        samplers, channels = anim.samplers or [], anim.channels or []
        if not isinstance(samplers, list) or not isinstance(channels, list):
            return f"animation {i} has samplers or channels that are not lists"
        for s in samplers:
            if not (ref(s.input, "accessors", False) and ref(s.output, "accessors", False)) or \
                    not (s.interpolation is None or isinstance(s.interpolation, str)):
                return f"animation {i} has a sampler naming an accessor that does not exist"
        for c in channels:
            if not _index(c.sampler, len(samplers)) or c.target is None or not ref(c.target.node, "nodes") or \
                    not (c.target.path is None or isinstance(c.target.path, str)):
                return f"animation {i} has a channel naming a sampler or node that does not exist"
    for i, tex in enumerate(lists["textures"]):
        if not ref(tex.source, "images"):
            return f"texture {i} names an image that does not exist"
    for i, image in enumerate(lists["images"]):
        if not ref(image.bufferView, "bufferViews") or not (image.uri is None or isinstance(image.uri, str)):
            return f"image {i} names a buffer view that does not exist"
    for i, material in enumerate(lists["materials"]):
        pbr = material.pbrMetallicRoughness
        if pbr is None:
            continue
        if pbr.baseColorFactor is not None and not _numbers(pbr.baseColorFactor, 4):
            return f"material {i} has a base colour that is not 4 finite numbers"
        if pbr.baseColorTexture is not None and not ref(pbr.baseColorTexture.index, "textures", False):
            return f"material {i} names a texture that does not exist"
    return None


class GltfDocument:
    """A glTF document (pygltflib's `GLTF2`, as `doc`) with its buffers and accessors read on demand.

    Parameters
    ----------
    path : str
        The file, for messages and for buffers given by relative URI.
    doc : pygltflib.GLTF2
    error : type of Exception
        Raised (with the file named) for any malformed buffer or accessor.
    """

    def __init__(self, path: str, doc, error: type[Exception] = ValueError):
        self.path, self.doc, self.error = path, doc, error
        self._buffers: dict[int, bytes] = {}

    def buffer(self, index: int) -> bytes:
        """The bytes of buffer `index` (the GLB's binary chunk when it has no URI)."""
        if index not in self._buffers:
            try:
                buf = self.doc.buffers[index]
            except (IndexError, TypeError):
                raise self.error(f"{self.path}: buffer {index} does not exist") from None
            if buf.uri is None:
                data = self.doc.binary_blob()
            elif buf.uri.startswith("data:"):
                try:
                    data = base64.b64decode(buf.uri.split(",", 1)[-1], validate=True)
                except ValueError:
                    raise self.error(f"{self.path}: buffer {index} has a malformed data URI") from None
            else:
                try:
                    data = (Path(self.path).parent / buf.uri).read_bytes()
                except OSError as e:
                    raise self.error(f"{self.path}: buffer {buf.uri!r} cannot be read ({e.strerror})") from None
            if data is None or len(data) < (buf.byteLength or 0):
                raise self.error(f"{self.path}: buffer {index} is shorter than its byteLength")
            self._buffers[index] = data
        return self._buffers[index]

    def view(self, index: int) -> bytes:
        """The bytes of buffer view `index` (an image, say)."""
        bv = self.doc.bufferViews[index]
        start = bv.byteOffset or 0
        return self.buffer(bv.buffer)[start:start + bv.byteLength]

    def _view(self, view_index: int, dtype: np.dtype, width: int, count: int, offset: int) -> np.ndarray:
        bv = self.doc.bufferViews[view_index]
        item = dtype.itemsize * width
        stride = bv.byteStride or item
        start = (bv.byteOffset or 0) + offset
        blob = self.buffer(bv.buffer)
        end = start + stride * (count - 1) + item
        if count and end > len(blob):
            raise self.error(f"{self.path}: an accessor reads past the end of buffer {bv.buffer}")
        raw = np.frombuffer(blob, dtype=np.uint8, count=max(end - start, 0), offset=start)
        rows = np.lib.stride_tricks.as_strided(raw, shape=(count, item), strides=(stride, 1))
        return np.frombuffer(rows.copy().tobytes(), dtype=dtype).reshape(count, width)

    def accessor(self, index: int) -> np.ndarray:
        """(count, width) values of accessor `index`: float64 for floats and normalized integers (mapped to
        [0, 1] or [-1, 1]), int64 for other integers. Non-finite floats are refused."""
        try:
            a = self.doc.accessors[index]
            dtype = np.dtype(COMPONENT_TYPES[a.componentType]).newbyteorder("<")
            width = WIDTHS[a.type]
            out = (self._view(a.bufferView, dtype, width, a.count, a.byteOffset or 0) if a.bufferView is not None
                   else np.zeros((a.count, width), dtype))
            if a.sparse is not None and a.sparse.count:
                s = a.sparse
                idx_dtype = np.dtype(COMPONENT_TYPES[s.indices.componentType]).newbyteorder("<")
                idx = self._view(s.indices.bufferView, idx_dtype, 1, s.count, s.indices.byteOffset or 0)[:, 0]
                out = out.copy()
                out[idx.astype(np.int64)] = self._view(s.values.bufferView, dtype, width, s.count,
                                                       s.values.byteOffset or 0)
        except (IndexError, KeyError, TypeError, ValueError, AttributeError) as e:
            raise self.error(f"{self.path}: accessor {index} is malformed ({e})") from None
        if dtype.kind == "f" or a.normalized:
            out = out.astype(np.float64)
            if a.normalized and dtype.kind in "iu":
                out = np.maximum(out / np.iinfo(dtype).max, -1.0)
            if not np.isfinite(out).all():
                raise self.error(f"{self.path}: accessor {index} holds non-finite values")
            return out
        return out.astype(np.int64)


def read_gltf(path: str | os.PathLike, error: type[Exception] = ValueError, embed: bool = False) -> GltfDocument:
    """Load a .glb/.vrm (by its magic bytes) or .gltf file.

    Parameters
    ----------
    embed : bool
        Gather every buffer into the document's binary blob (for writing the document out again).

    Raises
    ------
    error
        A missing, unreadable or corrupt file, naming it.
    """
    import pygltflib as gl

    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except (FileNotFoundError, IsADirectoryError):
        raise error(f"{path}: no such file") from None
    except OSError as e:
        raise error(f"{path}: cannot read ({e.strerror or e})") from None
    try:
        if head == b"glTF":
            doc = gl.GLTF2.load_binary(path)
        else:
            doc = gl.GLTF2.load_json(path)
            if embed:
                doc.convert_buffers(gl.BufferFormat.BINARYBLOB)
    except Exception as e:  # pygltflib raises plain exceptions (JSON, struct) on a corrupt file
        raise error(f"{path}: not a readable glTF file ({type(e).__name__}: {e})") from None
    if doc is None:
        raise error(f"{path}: not a readable glTF file")
    try:
        problem = document_problem(doc)
    except (AttributeError, TypeError, ValueError) as e:  # an object where a list or number belongs
        problem = f"malformed ({type(e).__name__}: {e})"
    if problem:
        raise error(f"{path}: not a valid glTF file: {problem}")
    return GltfDocument(path, doc, error)
