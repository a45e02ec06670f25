"""An independent glTF 2.0 player for the tests and the fidelity benchmark: reads a file and poses it the way
the glTF 2.0 specification tells a player to, with numpy only.

* every node's local matrix is T · R · S (or its `matrix`), animated channels overriding the rest values;
  world matrices run down the whole node hierarchy of the default scene;
* STEP, LINEAR (quaternions slerped on the shortest arc) and CUBICSPLINE (Hermite, tangents scaled by the
  key interval) samplers, clamped outside the keys;
* a skinned primitive is  v' = sum_k w_k · W(joint_k) · IBM_k · v  in world space (the mesh node's own
  transform is ignored, as the specification says); an unskinned primitive follows its node's world matrix;
* weights that do not sum to one (which the specification forbids and the Khronos validator reports as
  ACCESSOR_WEIGHTS_NON_NORMALIZED) are divided by their sum, as three.js's GLTFLoader and Blender's armature
  deform both do: without it such vertices are pulled toward the skeleton's origin, which no player shows;
* morph targets add  sum_t weight_t · delta_t  before skinning; the weights come from the node, else the
  mesh, and are overridden by a `weights` channel.

Nothing here imports Kinetre (nor a glTF library): it reads the JSON, decodes accessors and interpolates
animations itself, so a mistake in an exporter or loader cannot be cancelled by the same mistake in the check.
"""
from __future__ import annotations

import base64
import json
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_SLOT = {"translation": 0, "rotation": 1, "scale": 2}
TRIANGLES = 4


class Track(NamedTuple):
    """One animation channel: the node, the property ("translation", "rotation", "scale", "weights"), the
    interpolation, the key times (K,) and the values ((K, n), or (3K, n) for CUBICSPLINE)."""

    node: int
    path: str
    interpolation: str
    times: np.ndarray
    values: np.ndarray

    def at(self, t: float) -> np.ndarray:
        return sample(self.times, self.values, self.interpolation, t, self.path == "rotation")


@dataclass(frozen=True)
class Piece:
    """One drawn primitive: the mesh node that draws it, the primitive's index in its mesh, and where its
    vertices sit in `GltfFile.vertices`'s rows."""

    node: int
    mesh: int
    primitive: int
    start: int
    count: int


def normalised(weights: np.ndarray) -> np.ndarray:
    """(V, 4) skin weights divided by their sum; a vertex with none is bound to its first joint (three.js's
    SkinnedMesh.normalizeSkinWeights)."""
    total = weights.sum(axis=1, keepdims=True)
    return np.where(total > 0, weights / np.where(total > 0, total, 1.0), np.eye(weights.shape[1])[0])


class GltfFile:
    """A .glb/.gltf file posed at any time of any of its animations, every drawn primitive in world space."""

    def __init__(self, path):
        self.path = Path(path)
        self.doc, self.blob = read_document(self.path)
        d = self.doc
        self.parent = {c: i for i, n in enumerate(d.nodes) for c in (n.children or [])}
        scene = d.scenes[d.scene or 0].nodes if d.scenes else [i for i in range(len(d.nodes)) if i not in self.parent]
        self.order = []                      # the default scene's nodes, parents first (depth first)
        stack = list(reversed(scene))
        while stack:
            i = stack.pop()
            self.order.append(i)
            stack.extend(reversed(d.nodes[i].children or []))
        self.pieces: list[Piece] = []
        self._prims = []                     # per piece: positions, morph deltas, joints, weights
        start = 0
        for i in self.order:
            node = d.nodes[i]
            if node.mesh is None:
                continue
            for k, prim in enumerate(d.meshes[node.mesh].primitives):
                if (prim.mode if prim.mode is not None else TRIANGLES) != TRIANGLES:
                    continue             # points and lines have no surface to compare
                pos = self.accessor(prim.attributes.POSITION).astype(np.float64)
                deltas = np.stack([self.accessor(t["POSITION"] if isinstance(t, dict) else t.POSITION)
                                   for t in prim.targets]).astype(np.float64) if prim.targets else None
                skinned = node.skin is not None and prim.attributes.JOINTS_0 is not None
                joints = self.accessor(prim.attributes.JOINTS_0).astype(np.int64) if skinned else None
                weights = normalised(self.accessor(prim.attributes.WEIGHTS_0).astype(np.float64)) if skinned \
                    else None
                self._prims.append((pos, deltas, joints, weights))
                self.pieces.append(Piece(i, node.mesh, k, start, len(pos)))
                start += len(pos)
        self.vertex_count = start
        self._channels: dict[int, list[Track]] = {}
        self._ibm: dict[int, np.ndarray] = {}

    # ---- data -------------------------------------------------------------------------------------------
    def buffer(self, index: int) -> bytes:
        buf = self.doc.buffers[index]
        if buf.uri is None:
            return self.blob
        if buf.uri.startswith("data:"):
            return base64.b64decode(buf.uri.split(",", 1)[1])
        return (self.path.parent / buf.uri).read_bytes()

    def accessor(self, index: int) -> np.ndarray:
        """(count, width) values of an accessor: byteStride, normalized integers and sparse values handled."""
        a = self.doc.accessors[index]
        dtype = np.dtype(_DTYPES[a.componentType]).newbyteorder("<")
        width = _WIDTH[a.type]
        if a.bufferView is None:
            out = np.zeros((a.count, width), dtype)
        else:
            out = self._view(a.bufferView, (a.byteOffset or 0), a.count, dtype, width)
        if a.sparse is not None:
            s = a.sparse
            idx = self._view(s.indices.bufferView, s.indices.byteOffset or 0, s.count,
                             np.dtype(_DTYPES[s.indices.componentType]).newbyteorder("<"), 1)[:, 0]
            out = out.copy()
            out[idx.astype(np.int64)] = self._view(s.values.bufferView, s.values.byteOffset or 0, s.count, dtype,
                                                   width)
        if a.normalized:
            out = np.maximum(out.astype(np.float64) / np.iinfo(dtype).max, -1.0)
        return out

    def _view(self, view: int, offset: int, count: int, dtype, width: int) -> np.ndarray:
        bv = self.doc.bufferViews[view]
        item = dtype.itemsize * width
        stride = bv.byteStride or item
        start = (bv.byteOffset or 0) + offset
        raw = np.frombuffer(self.buffer(bv.buffer), dtype=np.uint8, count=stride * (count - 1) + item, offset=start)
        rows = np.lib.stride_tricks.as_strided(raw, shape=(count, item), strides=(stride, 1))
        return np.frombuffer(rows.copy().tobytes(), dtype=dtype).reshape(count, width)

    def triangles(self) -> np.ndarray:
        """(T, 3) triangles of every piece, indexing `vertices`'s rows."""
        out = []
        for piece in self.pieces:
            prim = self.doc.meshes[piece.mesh].primitives[piece.primitive]
            tri = (self.accessor(prim.indices).astype(np.int64).reshape(-1, 3) if prim.indices is not None
                   else np.arange(piece.count).reshape(-1, 3))
            out.append(tri + piece.start)
        return np.concatenate(out) if out else np.zeros((0, 3), np.int64)

    # ---- animation ------------------------------------------------------------------------------------
    def animation_index(self, which: str | int | None) -> int | None:
        """The index of an animation given by name or index (None: no animation, the rest pose)."""
        if which is None:
            return None
        names = [a.name for a in self.doc.animations]
        if isinstance(which, str) and which in names:
            return names.index(which)
        if str(which).isdigit() and int(which) < len(names):
            return int(which)
        raise KeyError(f"{self.path}: no animation {which!r} (has {names})")

    def channels(self, animation: str | int | None) -> list[Track]:
        """The channels of an animation (None: none), decoded once."""
        index = self.animation_index(animation)
        if index is None:
            return []
        if index in self._channels:
            return self._channels[index]
        anim = self.doc.animations[index]
        out = []
        for ch in anim.channels:
            if ch.target is None or ch.target.node is None:
                continue
            s = anim.samplers[ch.sampler]
            values = self.accessor(s.output).astype(np.float64)
            if ch.target.path == "weights":
                keys = self.accessor(s.input).shape[0] * (3 if s.interpolation == "CUBICSPLINE" else 1)
                values = values.reshape(keys, -1)
            out.append(Track(ch.target.node, ch.target.path, s.interpolation or "LINEAR",
                             self.accessor(s.input).astype(np.float64)[:, 0], values))
        self._channels[index] = out
        return out

    def time_range(self, animation: str | int) -> tuple[float, float]:
        """First and last key time of an animation (seconds)."""
        tracks = self.channels(animation)
        return min(float(t.times[0]) for t in tracks), max(float(t.times[-1]) for t in tracks)

    def local_matrices(self, time: float, animation: str | int | None = 0, tracks=None) -> list[np.ndarray]:
        """Each node's local matrix at `time`: rest TRS overridden by the animation's channels."""
        d = self.doc
        trs = [[np.array(n.translation or [0, 0, 0], float), np.array(n.rotation or [0, 0, 0, 1], float),
                np.array(n.scale or [1, 1, 1], float)] for n in d.nodes]
        animated = set()
        for track in self.channels(animation) if tracks is None else tracks:
            if track.path in _SLOT:
                trs[track.node][_SLOT[track.path]] = track.at(time)
                animated.add(track.node)
        out = []
        for i, (n, (t, q, s)) in enumerate(zip(d.nodes, trs)):
            if n.matrix is not None and i not in animated:
                out.append(np.array(n.matrix, float).reshape(4, 4).T)     # column-major in the file
                continue
            m = np.eye(4)
            m[:3, :3] = quaternion_matrix(q) * s[None, :]
            m[:3, 3] = t
            out.append(m)
        return out

    def world_matrices(self, time: float, animation: str | int | None = 0, tracks=None) -> list[np.ndarray]:
        """Each node's world matrix at `time` (nodes outside the default scene: relative to their root)."""
        local = self.local_matrices(time, animation, tracks)
        world: list[np.ndarray | None] = [None] * len(local)

        def world_of(i):
            if world[i] is None:
                p = self.parent.get(i)
                world[i] = local[i] if p is None else world_of(p) @ local[i]
            return world[i]

        return [world_of(i) for i in range(len(local))]

    def morph_weights(self, time: float, tracks) -> dict[int, np.ndarray]:
        """Morph weights per mesh node at `time`: the node's, else its mesh's, overridden by the channels."""
        out = {}
        for piece in self.pieces:
            node = self.doc.nodes[piece.node]
            w = getattr(node, "weights", None)
            if w is None:
                w = self.doc.meshes[piece.mesh].weights
            if w is not None:
                out[piece.node] = np.array(w, float)
        for track in tracks:
            if track.path == "weights":
                out[track.node] = track.at(time)
        return out

    def vertices(self, time: float = 0.0, animation: str | int | None = 0) -> np.ndarray:
        """(V, 3) world positions of every drawn vertex at `time` of `animation` (None: the rest pose), pieces
        in the default scene's depth-first order."""
        tracks = self.channels(animation)
        world = self.world_matrices(time, animation, tracks)
        morph = self.morph_weights(time, tracks)
        out = np.empty((self.vertex_count, 3))
        stacked = np.stack(world)
        joint_m = {}                          # per skin: (J, 4, 4) joint world x inverse bind
        for piece, (pos, deltas, joints, weights) in zip(self.pieces, self._prims):
            if deltas is not None and piece.node in morph:
                w = morph[piece.node]
                pos = pos + np.einsum("t,tvc->vc", w[:len(deltas)], deltas[:len(w)])
            node = self.doc.nodes[piece.node]
            if joints is None:
                m = world[piece.node]
                out[piece.start:piece.start + piece.count] = pos @ m[:3, :3].T + m[:3, 3]
                continue
            if node.skin not in joint_m:
                joint_m[node.skin] = stacked[self.doc.skins[node.skin].joints] @ self.inverse_binds(node.skin)
            blend = np.einsum("vk,vkij->vij", weights, joint_m[node.skin][joints])
            out[piece.start:piece.start + piece.count] = (np.einsum("vij,vj->vi", blend[:, :3, :3], pos)
                                                         + blend[:, :3, 3])
        return out

    def inverse_binds(self, skin: int) -> np.ndarray:
        """(J, 4, 4) row-major inverse bind matrices of a skin (identity when the file gives none)."""
        if skin not in self._ibm:
            s = self.doc.skins[skin]
            self._ibm[skin] = (self.accessor(s.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
                               if s.inverseBindMatrices is not None else np.tile(np.eye(4), (len(s.joints), 1, 1)))
        return self._ibm[skin]

    def joint_weights(self) -> dict[int, float]:
        """Total skin weight of each joint node over every skinned piece (joints that move no vertex: 0)."""
        total = {j: 0.0 for j in self.skin_joints()}
        for piece, (_, _, joints, weights) in zip(self.pieces, self._prims):
            if joints is not None:
                skin = self.doc.skins[self.doc.nodes[piece.node].skin].joints
                sums = np.bincount(joints.ravel(), weights=weights.ravel(), minlength=len(skin))
                for j, w in zip(skin, sums):
                    total[j] += float(w)
        return total

    def skin_joints(self) -> list[int]:
        """The joint nodes of every skin (each once, in skin order)."""
        out: list[int] = []
        for skin in self.doc.skins or []:
            out += [j for j in skin.joints if j not in out]
        return out


class JsonObject:
    """A glTF JSON object read by attribute, as pygltflib's classes are (`node.mesh`, `prim.attributes.POSITION`);
    a property the file leaves out reads as None."""

    __slots__ = ("_fields", "_wrapped")

    def __init__(self, fields: dict):
        self._fields, self._wrapped = fields, {}

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        if name not in self._wrapped:
            self._wrapped[name] = _wrap(self._fields.get(name))
        return self._wrapped[name]

    def __getitem__(self, name):
        return getattr(self, name)


def _wrap(value):
    if isinstance(value, dict):
        return JsonObject(value)
    if isinstance(value, list):
        return [_wrap(v) for v in value]
    return value


def read_document(path: Path) -> tuple[JsonObject, bytes | None]:
    """The JSON document of a .glb or .gltf and the GLB's binary chunk (None for .gltf). Read here rather than
    with pygltflib, whose JSON decoding takes seconds on a file with a few thousand objects."""
    data = path.read_bytes()
    if data[:4] != b"glTF":
        return JsonObject(json.loads(data)), None
    length, = struct.unpack_from("<I", data, 8)
    offset, doc, blob = 12, None, None
    while offset < length:
        size, kind = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8:offset + 8 + size]
        if kind == 0x4E4F534A:       # "JSON"
            doc = json.loads(chunk)
        elif kind == 0x004E4942:     # "BIN"
            blob = chunk
        offset += 8 + size
    return JsonObject(doc), blob


class GltfPlayer(GltfFile):
    """One skinned primitive of a file (by default the first skinned node's first), skinned in its mesh
    node's frame at any time of one animation (by default the first)."""

    def __init__(self, path, mesh_node: int | None = None, primitive: int = 0, animation: str | int = 0):
        super().__init__(path)
        d = self.doc
        self.mesh_node = next(i for i, n in enumerate(d.nodes) if n.skin is not None) if mesh_node is None \
            else mesh_node
        prim = d.meshes[d.nodes[self.mesh_node].mesh].primitives[primitive]
        self.primitive = prim
        self.positions = self.accessor(prim.attributes.POSITION).astype(np.float64)
        self.joints = self.accessor(prim.attributes.JOINTS_0).astype(np.int64)
        self.weights = normalised(self.accessor(prim.attributes.WEIGHTS_0).astype(np.float64))
        skin = d.skins[d.nodes[self.mesh_node].skin]
        self.skin_joints = list(skin.joints)
        self.inverse_bind = self.accessor(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
        self.animation = animation
        self.tracks = self.channels(animation)

    def local_matrices(self, time: float, animation=None, tracks=None) -> list[np.ndarray]:
        return GltfFile.local_matrices(self, time, self.animation, self.tracks if tracks is None else tracks)

    def skin(self, time: float) -> np.ndarray:
        """(V, 3) skinned positions of the primitive at `time` (seconds), in its mesh node's frame."""
        world = self.world_matrices(time, self.animation, self.tracks)
        mesh_inv = np.linalg.inv(world[self.mesh_node])
        joint_m = np.stack([mesh_inv @ world[j] @ ib for j, ib in zip(self.skin_joints, self.inverse_bind)])
        blend = np.einsum("vk,vkij->vij", self.weights, joint_m[self.joints])
        return np.einsum("vij,vj->vi", blend[:, :3, :3], self.positions) + blend[:, :3, 3]


def sample(times: np.ndarray, values: np.ndarray, interpolation: str, t: float, rotation: bool = False):
    """One sampler's value at time `t` (glTF 2.0 Appendix C), clamped to the first and last key."""
    cubic = interpolation == "CUBICSPLINE"
    v = values[1::3] if cubic else values
    if t <= times[0] or len(times) == 1:
        out = v[0]
    elif t >= times[-1]:
        out = v[-1]
    else:
        k = int(np.searchsorted(times, t, side="right")) - 1
        dt = times[k + 1] - times[k]
        u = (t - times[k]) / dt
        if interpolation == "STEP":
            out = v[k]
        elif cubic:
            out = ((2 * u ** 3 - 3 * u ** 2 + 1) * v[k] + (u ** 3 - 2 * u ** 2 + u) * dt * values[3 * k + 2]
                   + (-2 * u ** 3 + 3 * u ** 2) * v[k + 1] + (u ** 3 - u ** 2) * dt * values[3 * (k + 1)])
        elif rotation:
            return slerp(v[k], v[k + 1], u)
        else:
            out = (1 - u) * v[k] + u * v[k + 1]
    return out / np.linalg.norm(out) if rotation else out


def slerp(a: np.ndarray, b: np.ndarray, u: float) -> np.ndarray:
    dot = float(a @ b)
    if dot < 0:  # the shortest arc
        b, dot = -b, -dot
    if dot > 0.9995:
        q = (1 - u) * a + u * b
    else:
        th = np.arccos(dot)
        q = (np.sin((1 - u) * th) * a + np.sin(u * th) * b) / np.sin(th)
    return q / np.linalg.norm(q)


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
