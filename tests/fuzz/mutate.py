"""Structure-aware mutations for the fuzz tests, as hypothesis strategies: each takes a valid file's bytes (or
parsed JSON) and draws a broken variant of it, the way a careless tool or a hostile user would break it.

Byte-level: bit flips, truncation, deleted / duplicated / inserted runs, hostile 32-bit words.
Text formats (OBJ, ASCII PLY, OFF, BVH, headers): a number replaced by a hostile one (NaN, inf, huge, negative,
off by one), lines deleted or duplicated. JSON (glTF, takes, intrinsics, studio messages): a value anywhere in
the tree replaced by one of another type or a hostile number, a key deleted, a list cut short.
Binary layouts (PLY, STL, GLB): the counts and the index / vertex records the format puts at known offsets.
"""
from __future__ import annotations

import json
import re
import struct

from hypothesis import strategies as st

HOSTILE_NUMBERS = ("nan", "-nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "0", "-0", "-1", "1", "2", "3",
                   "255", "256", "65535", "65536", "2147483647", "2147483648", "-2147483648", "4294967295",
                   "4294967296", "9223372036854775807", "18446744073709551616", "99999999999999999999", "1e38",
                   "3.4e38", "0.5", "-0.5", "1e9", "", "x")
HOSTILE_JSON = (None, True, False, 0, -1, 1, 2, 3, 4, 255, 65535, 2**31 - 1, 2**31, 2**32, 2**53, 2**63, 2**64,
                -(2**31), 0.5, -0.0, 1e308, -1e308, 1e-320, "", "x", "-1", [], [0], [None], {}, {"x": 1},
                [[0, 0, 0]], "NaN")
# 32-bit words a reader must not trust: huge/negative indices and counts, NaN and infinite floats
HOSTILE_WORDS = (b"\xff\xff\xff\xff", b"\xff\xff\xff\x7f", b"\x00\x00\x00\x80", b"\x00\x00\xc0\x7f",
                 b"\x00\x00\x80\x7f", b"\x00\x00\x80\xff", b"\xff\xff\x7f\x7f", b"\x00\x00\x00\x00",
                 b"\x01\x00\x00\x00", b"\x00\x00\x01\x00", b"\x10\x27\x00\x00", b"\xa0\x86\x01\x00")
NUMBER = re.compile(rb"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")


@st.composite
def bytes_mutation(draw, data: bytes, max_ops: int = 3) -> bytes:
    """`data` with 1..max_ops byte-level edits."""
    out = bytearray(data)
    for _ in range(draw(st.integers(1, max_ops))):
        n = len(out)
        op = draw(st.sampled_from(("flip", "truncate", "delete", "duplicate", "insert", "word")))
        pos = draw(st.integers(0, max(n - 1, 0)))
        if op == "flip" and n:
            out[pos] ^= 1 << draw(st.integers(0, 7))
        elif op == "truncate":
            del out[pos:]
        elif op == "delete":
            del out[pos:pos + draw(st.integers(1, 64))]
        elif op == "duplicate":
            out[pos:pos] = out[pos:pos + draw(st.integers(1, 64))]
        elif op == "insert":
            out[pos:pos] = draw(st.binary(min_size=1, max_size=16))
        else:
            out[pos:pos + 4] = draw(st.sampled_from(HOSTILE_WORDS))
    return bytes(out)


@st.composite
def text_mutation(draw, data: bytes, max_ops: int = 3) -> bytes:
    """`data` (a text format) with hostile numbers in place of some of its numbers, lines deleted or duplicated."""
    out = data
    for _ in range(draw(st.integers(1, max_ops))):
        op = draw(st.sampled_from(("number", "number", "number", "line", "bytes")))
        if op == "number":
            spots = [m.span() for m in NUMBER.finditer(out)]
            if not spots:
                continue
            # bias toward the first numbers: the counts and sizes a header declares
            k = draw(st.one_of(st.integers(0, min(len(spots), 16) - 1), st.integers(0, len(spots) - 1)))
            a, b = spots[k]
            out = out[:a] + draw(st.sampled_from(HOSTILE_NUMBERS)).encode() + out[b:]
        elif op == "line":
            lines = out.split(b"\n")
            k = draw(st.integers(0, len(lines) - 1))
            if draw(st.booleans()):
                del lines[k]
            else:
                lines.insert(k, lines[k])
            out = b"\n".join(lines)
        else:
            out = draw(bytes_mutation(out, 1))
    return out


def _paths(value, prefix=()):
    """Every (path, value) in a JSON tree, containers included."""
    yield prefix, value
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _paths(v, prefix + (i,))


def _parent(tree, path):
    for k in path[:-1]:
        tree = tree[k]
    return tree


@st.composite
def json_mutation(draw, value, max_ops: int = 3, prefer=None):
    """A deep copy of a JSON value with 1..max_ops edits; `prefer(path)` true marks the paths to pick more often
    (the indices and counts a reader trusts)."""
    tree = json.loads(json.dumps(value))
    for _ in range(draw(st.integers(1, max_ops))):
        paths = [p for p, _ in _paths(tree) if p]
        if not paths:
            return _hostile(draw)
        if prefer is not None:
            favoured = [p for p in paths if prefer(p)]
            if favoured and draw(st.booleans()):
                paths = favoured
        path = draw(st.sampled_from(paths))
        parent, key = _parent(tree, path), path[-1]
        op = draw(st.sampled_from(("replace", "replace", "replace", "delete", "shorten", "nudge")))
        current = parent[key]
        if op == "delete":
            del parent[key]
        elif op == "shorten" and isinstance(current, list) and current:
            del current[draw(st.integers(0, len(current) - 1)):]
        elif op == "nudge" and isinstance(current, int) and not isinstance(current, bool):
            parent[key] = current + draw(st.sampled_from((-1, 1, 1000, -1000, 2**31)))
        else:
            parent[key] = _hostile(draw)
    return tree


def _hostile(draw):
    """A fresh copy of a hostile JSON value (later edits must not change the shared one)."""
    return json.loads(json.dumps(draw(st.sampled_from(HOSTILE_JSON))))


def json_text(value) -> bytes:
    """JSON as a reader would meet it, NaN and Infinity included (Python's json writes them)."""
    return json.dumps(value).encode()


# ---- binary layouts ----------------------------------------------------------------------------------------

def split_header(data: bytes, end: bytes) -> tuple[bytes, bytes]:
    i = data.index(end) + len(end)
    return data[:i], data[i:]


@st.composite
def records_mutation(draw, body: bytes, start: int, size: int, count: int, fields: tuple[int, ...]) -> bytes:
    """Hostile 32-bit words written into `count` records of `size` bytes from `start` (at field offsets)."""
    out = bytearray(body)
    if count <= 0:
        return bytes(out)
    for _ in range(draw(st.integers(1, 3))):
        r = draw(st.integers(0, count - 1))
        at = start + r * size + draw(st.sampled_from(fields))
        out[at:at + 4] = draw(st.sampled_from(HOSTILE_WORDS))
    return bytes(out)


@st.composite
def ply_mutation(draw, data: bytes) -> bytes:
    """A binary little-endian PLY (float x, y, z; uchar count + int indices): header counts, vertex floats,
    face list counts and indices."""
    header, body = split_header(data, b"end_header\n")
    nv = int(re.search(rb"element vertex (\d+)", header).group(1))
    nf = int(re.search(rb"element face (\d+)", header).group(1))
    part = draw(st.sampled_from(("header", "vertices", "faces", "counts", "bytes")))
    if part == "header":
        return draw(text_mutation(header, 2)) + body
    if part == "vertices":
        return header + draw(records_mutation(body, 0, 12, nv, (0, 4, 8)))
    if part == "faces":
        return header + draw(records_mutation(body, nv * 12, 13, nf, (1, 5, 9)))
    if part == "counts":
        out = bytearray(body)
        for _ in range(draw(st.integers(1, 3))):
            out[nv * 12 + 13 * draw(st.integers(0, nf - 1))] = draw(st.sampled_from((0, 1, 2, 4, 200, 255)))
        return header + bytes(out)
    return draw(bytes_mutation(data))


@st.composite
def stl_mutation(draw, data: bytes) -> bytes:
    """A binary STL: the triangle count at byte 80 and the records' normals and corners."""
    (count,) = struct.unpack_from("<I", data, 80)
    part = draw(st.sampled_from(("count", "records", "bytes")))
    if part == "count":
        return data[:80] + draw(st.sampled_from(HOSTILE_WORDS)) + data[84:]
    if part == "records":
        return data[:84] + draw(records_mutation(data[84:], 0, 50, count, (0, 12, 16, 20, 24, 36, 44)))
    return draw(bytes_mutation(data))


def glb_parts(data: bytes) -> tuple[dict, bytes]:
    """(JSON, binary chunk) of a GLB."""
    (json_len,) = struct.unpack_from("<I", data, 12)
    doc = json.loads(data[20:20 + json_len])
    rest = data[20 + json_len:]
    return doc, rest[8:] if len(rest) >= 8 else b""


def glb_bytes(doc, blob: bytes) -> bytes:
    text = json_text(doc)
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    chunks = struct.pack("<I4s", len(text), b"JSON") + text
    if blob:
        chunks += struct.pack("<I4s", len(blob), b"BIN\0") + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


_GLTF_INDEX_KEYS = {"bufferView", "buffer", "byteOffset", "byteLength", "byteStride", "count", "componentType",
                    "type", "indices", "mesh", "skin", "children", "joints", "inverseBindMatrices", "input",
                    "output", "sampler", "node", "nodes", "source", "index", "scene", "POSITION", "NORMAL",
                    "JOINTS_0", "WEIGHTS_0", "TEXCOORD_0", "matrix", "translation", "rotation", "scale",
                    "material", "sparse", "humanBones"}


def gltf_index_path(path) -> bool:
    """A path through a glTF JSON that holds an index, a count, an offset or a transform."""
    return any(isinstance(k, str) and k in _GLTF_INDEX_KEYS for k in path[-2:])


@st.composite
def glb_mutation(draw, data: bytes) -> bytes:
    """A GLB: its JSON bent (indices, counts, offsets, transforms first), its binary chunk's accessor data
    overwritten with hostile words (indices past the vertex count, NaN floats), or its container's bytes."""
    doc, blob = glb_parts(data)
    part = draw(st.sampled_from(("json", "json", "accessor", "bytes")))
    if part == "json":
        return glb_bytes(draw(json_mutation(doc, prefer=gltf_index_path)), blob)
    if part == "accessor":
        accessors = [a for a in doc.get("accessors", []) if a.get("bufferView") is not None]
        a = draw(st.sampled_from(accessors))
        view = doc["bufferViews"][a["bufferView"]]
        start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        item = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}[a["componentType"]]
        count = a["count"] * {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}.get(a["type"], 1)
        out = bytearray(blob)
        for _ in range(draw(st.integers(1, 4))):
            at = start + item * draw(st.integers(0, count - 1))
            out[at:at + item] = draw(st.sampled_from(HOSTILE_WORDS))[:item]
        return glb_bytes(doc, bytes(out))
    return draw(bytes_mutation(data))


@st.composite
def jsonl_mutation(draw, data: bytes) -> bytes:
    """A JSON-lines take: values in its header or frames bent, lines lost or repeated, bytes broken."""
    lines = data.split(b"\n")
    part = draw(st.sampled_from(("record", "record", "lines", "bytes")))
    if part == "record":
        k = draw(st.one_of(st.just(0), st.integers(0, len(lines) - 1)))
        if lines[k].strip():
            lines[k] = json_text(draw(json_mutation(json.loads(lines[k]))))
        return b"\n".join(lines)
    if part == "lines":
        return draw(text_mutation(data, 2))
    return draw(bytes_mutation(data))
