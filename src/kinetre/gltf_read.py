"""Reading glTF 2.0 files, once for every stage (motion from animations, rigged avatars): the document with
its buffers (GLB chunk, data URIs, files next to it) and accessors decoded as glTF 2.0 §3.6 says (byteStride,
normalized integers, sparse substitution).

Every failure raises the error class the caller names (BadMotionError, BadAvatarError), naming the file.
"""
from __future__ import annotations

import base64
import os
from pathlib import Path

import numpy as np

COMPONENT_TYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
                   5126: np.float32}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


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
                data = base64.b64decode(buf.uri.split(",", 1)[1])
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
    return GltfDocument(path, doc, error)
