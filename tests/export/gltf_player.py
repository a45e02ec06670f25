"""An independent glTF skinning player for the tests: reads a written file with pygltflib and skins it
the way the glTF 2.0 spec tells a player to (joint world matrix x inverse bind matrix, weighted sum).

Nothing here imports Kinetre: it decodes accessors itself and interpolates the animation itself, so a
mistake in the exporter cannot be cancelled by the same mistake in the check.
"""
from __future__ import annotations

import base64
from pathlib import Path

import numpy as np
import pygltflib as gl

_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class GltfPlayer:
    """Skin a skinned mesh primitive of a .glb/.gltf (by default the first) at any time of its first animation."""

    def __init__(self, path, mesh_node: int | None = None, primitive: int = 0):
        path = Path(path)
        self.doc = gl.GLTF2.load(str(path))
        if path.suffix.lower() == ".glb":
            self.blob = self.doc.binary_blob()
        else:
            uri = self.doc.buffers[0].uri
            self.blob = base64.b64decode(uri.split(",", 1)[1])
        d = self.doc
        self.mesh_node = next(i for i, n in enumerate(d.nodes) if n.skin is not None) if mesh_node is None \
            else mesh_node
        prim = d.meshes[d.nodes[self.mesh_node].mesh].primitives[primitive]
        self.primitive = prim
        self.positions = self.accessor(prim.attributes.POSITION).astype(np.float64)
        self.joints = self.accessor(prim.attributes.JOINTS_0).astype(np.int64)
        self.weights = self.accessor(prim.attributes.WEIGHTS_0).astype(np.float64)
        skin = d.skins[d.nodes[self.mesh_node].skin]
        self.skin_joints = list(skin.joints)
        # column-major in the file: reshape to (N, 4, 4) then transpose to row-major
        self.inverse_bind = self.accessor(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
        self.parent = {c: i for i, n in enumerate(d.nodes) for c in (n.children or [])}
        anim = d.animations[0]
        self.tracks = []
        for ch in anim.channels:
            s = anim.samplers[ch.sampler]
            self.tracks.append((ch.target.node, ch.target.path, s.interpolation,
                                self.accessor(s.input).astype(np.float64)[:, 0],
                                self.accessor(s.output).astype(np.float64)))

    def accessor(self, index: int) -> np.ndarray:
        """Decode an accessor (no sparse, handles byteStride and normalized integers)."""
        a = self.doc.accessors[index]
        bv = self.doc.bufferViews[a.bufferView]
        dtype = np.dtype(_DTYPES[a.componentType])
        width = _WIDTH[a.type]
        item = dtype.itemsize * width
        stride = bv.byteStride or item
        start = (bv.byteOffset or 0) + (a.byteOffset or 0)
        raw = np.frombuffer(self.blob, dtype=np.uint8, count=stride * (a.count - 1) + item, offset=start)
        rows = np.lib.stride_tricks.as_strided(raw, shape=(a.count, item), strides=(stride, 1))
        out = np.frombuffer(rows.copy().tobytes(), dtype=dtype).reshape(a.count, width)
        if a.normalized:
            out = out.astype(np.float64) / np.iinfo(dtype).max
        return out

    def local_matrices(self, time: float) -> list[np.ndarray]:
        """Each node's local matrix at `time`: rest TRS overridden by the animation's channels."""
        d = self.doc
        trs = [[np.array(n.translation or [0, 0, 0], float), np.array(n.rotation or [0, 0, 0, 1], float),
                np.array(n.scale or [1, 1, 1], float)] for n in d.nodes]
        for node, prop, interp, times, values in self.tracks:
            slot = {"translation": 0, "rotation": 1, "scale": 2}[prop]
            trs[node][slot] = _sample(times, values, time, interp, prop == "rotation")
        out = []
        for n, (t, q, s) in zip(d.nodes, trs):
            if n.matrix is not None:
                out.append(np.array(n.matrix, float).reshape(4, 4).T)
                continue
            m = np.eye(4)
            m[:3, :3] = _quat_to_matrix(q) * s[None, :]
            m[:3, 3] = t
            out.append(m)
        return out

    def skin(self, time: float) -> np.ndarray:
        """(V, 3) skinned positions at `time` (seconds)."""
        local = self.local_matrices(time)
        world = {}

        def world_of(i):
            if i not in world:
                p = self.parent.get(i)
                world[i] = local[i] if p is None else world_of(p) @ local[i]
            return world[i]

        mesh_inv = np.linalg.inv(world_of(self.mesh_node))
        joint_m = np.stack([mesh_inv @ world_of(j) @ ib for j, ib in zip(self.skin_joints, self.inverse_bind)])
        blend = np.einsum("vk,vkij->vij", self.weights, joint_m[self.joints])
        return np.einsum("vij,vj->vi", blend[:, :3, :3], self.positions) + blend[:, :3, 3]


def _sample(times, values, t, interp, is_rotation):
    if t <= times[0]:
        return values[0]
    if t >= times[-1]:
        return values[-1]
    k = int(np.searchsorted(times, t, side="right")) - 1
    if interp == "STEP":
        return values[k]
    u = (t - times[k]) / (times[k + 1] - times[k])
    a, b = values[k], values[k + 1]
    if not is_rotation:
        return (1 - u) * a + u * b
    dot = float(a @ b)
    if dot < 0:  # shortest path
        b, dot = -b, -dot
    if dot > 0.9995:
        q = (1 - u) * a + u * b
    else:
        th = np.arccos(dot)
        q = (np.sin((1 - u) * th) * a + np.sin(u * th) * b) / np.sin(th)
    return q / np.linalg.norm(q)


def _quat_to_matrix(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
