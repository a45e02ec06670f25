"""A rigged glTF 2.0 / GLB / VRM file as an `Avatar`: node tree, the skin's joints in their bind pose, and
the skinned primitives (positions, JOINTS_0/WEIGHTS_0, normals, UVs, material colour and image).

The bind pose comes from the inverse bind matrices, not from the nodes' rest transforms (they may differ,
e.g. a file saved mid-animation): joint k's bind world matrix is B_k = M · IBM_k⁻¹, with M the world matrix
of the skinned mesh's node (the space the IBMs were computed in by exporters). Per the glTF spec a player
skins with  v' = Σ_k w_k · World_k · IBM_k · v  (the mesh node's own transform ignored), so with the joints
at B_k the mesh appears as M · v, where it was authored. Where the nodes' rest transforms disagree with B_k,
the joints' rest (local) transforms are replaced by the bind ones, so "rest" means "bind" everywhere below.

VRM 0.x (`extensions.VRM.humanoid.humanBones`, a list of {bone, node}) and VRM 1.0
(`extensions.VRMC_vrm.humanoid.humanBones`, a dict bone -> {node}) name the humanoid bones directly;
`Avatar.vrm_bones` keeps that map (human bone name -> skin joint index).
"""
from __future__ import annotations

import io
import os
import re
from dataclasses import dataclass, field

import numpy as np

from ..affine import affine_inverse
from ..errors import BadAvatarError
from ..gltf_read import GltfDocument, read_gltf
from ..rotation import quaternion_matrices

EXTENSIONS = (".glb", ".gltf", ".vrm")


@dataclass(frozen=True, eq=False)
class Primitive:
    """One skinned triangle primitive, vertices in the mesh's bind space.

    Attributes
    ----------
    node, mesh, index : int
        The glTF node holding the mesh, the mesh, and the primitive's index in it.
    positions, normals : (V, 3) float64
    joints : (V, 4) int64
        Indices into `Avatar.joints` (skin joint order), as JOINTS_0.
    weights : (V, 4) float64
        WEIGHTS_0, renormalised to sum 1 (avateering paper §3: LBS with weights normalised to sum 1).
    faces : (F, 3) int64
    uvs : (V, 2) float64 or None
    color : (4,) float64
        The material's base colour factor (linear RGBA).
    image : PIL.Image or None
        The base colour texture, decoded, when the material has one.
    """

    node: int
    mesh: int
    index: int
    positions: np.ndarray
    normals: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray | None
    color: np.ndarray
    image: object = None


@dataclass(frozen=True, eq=False)
class Avatar:
    """A rigged avatar: the glTF document, its node tree in the bind pose, one skin and its primitives.

    Attributes
    ----------
    source : str
    doc : pygltflib.GLTF2
        The parsed document (kept for export), its buffer in `blob`.
    node_parents : (N,) int64
        Parent node per node, -1 for scene roots.
    rest_local, rest_world : (N, 4, 4) float64
        Each node's local and world matrix in the bind pose.
    joints : (J,) int64
        The skin's joint nodes, in skin order.
    joint_names : tuple of str, (J,)
        Node names ("joint<k>" where a node has none).
    joint_parents : (J,) int64
        The nearest ancestor that is a joint, as a joint index; -1 if none.
    inverse_bind : (J, 4, 4) float64
    primitives : list of Primitive
    vrm_bones : dict
        VRM humanoid bone name -> joint index (empty for plain glTF).
    """

    source: str
    doc: object
    blob: bytes
    node_parents: np.ndarray
    rest_local: np.ndarray
    rest_world: np.ndarray
    joints: np.ndarray
    joint_names: tuple[str, ...]
    joint_parents: np.ndarray
    inverse_bind: np.ndarray
    primitives: list[Primitive]
    vrm_bones: dict = field(default_factory=dict)

    @property
    def bind_world(self) -> np.ndarray:
        """(J, 4, 4) world matrix of each joint in the bind pose."""
        return self.rest_world[self.joints]

    @property
    def bind_positions(self) -> np.ndarray:
        """(J, 3) joint positions in the bind pose (world)."""
        return self.rest_world[self.joints, :3, 3]

    @property
    def vertex_count(self) -> int:
        return sum(len(p.positions) for p in self.primitives)


def trs_matrix(translation, rotation, scale) -> np.ndarray:
    """(4, 4) T · R · S from glTF's translation (3), rotation quaternion (x, y, z, w) and scale (3)."""
    r = quaternion_matrices(np.asarray(rotation, dtype=np.float64))
    m = np.eye(4)
    m[:3, :3] = r * np.asarray(scale, dtype=np.float64)[None, :]
    m[:3, 3] = translation
    return m


def load_avatar(path: str | os.PathLike) -> Avatar:
    """Read a rigged .glb, .gltf or .vrm file.

    Raises
    ------
    BadAvatarError
        Missing/unreadable/corrupt file, no skin, no skinned triangles, bad accessors. The message names
        the file; a mesh without a skin is pointed to `kinetre animate` (possession needs no rig).
    """
    path = os.fspath(path)
    if not path.lower().endswith(EXTENSIONS):
        raise BadAvatarError(f"{path}: an avatar must be a rigged .glb, .gltf or .vrm file")
    # every buffer in one blob: the avatar is written out again with its own (export.py)
    reader = read_gltf(path, BadAvatarError, embed=True)
    return _build(reader)


def _build(reader: GltfDocument) -> Avatar:
    path, doc = reader.path, reader.doc
    blob = doc.binary_blob() or b""
    nodes = doc.nodes or []
    if not nodes:
        raise BadAvatarError(f"{path}: the file has no nodes")
    parents = np.full(len(nodes), -1, dtype=np.int64)
    for i, n in enumerate(nodes):
        for c in n.children or []:
            if not 0 <= c < len(nodes) or parents[c] >= 0:
                raise BadAvatarError(f"{path}: node {i} has a bad or shared child {c}")
            parents[c] = i
    skinned = [i for i, n in enumerate(nodes) if n.skin is not None and n.mesh is not None]
    if not skinned or not doc.skins:
        raise BadAvatarError(f"{path}: no skinned mesh (not a rigged avatar); an unrigged mesh is brought to "
                             f"life by possession instead: kinetre animate {os.path.basename(path)} --motion ...")
    # the skin used by the most skinned nodes (an avatar has one)
    skin_index = max({nodes[i].skin for i in skinned}, key=lambda s: sum(nodes[i].skin == s for i in skinned))
    skin = doc.skins[skin_index]
    joints = np.array(skin.joints, dtype=np.int64)
    if joints.size == 0 or (joints < 0).any() or (joints >= len(nodes)).any():
        raise BadAvatarError(f"{path}: skin {skin_index} has no or bad joints")
    if skin.inverseBindMatrices is None:
        ibm = np.tile(np.eye(4), (len(joints), 1, 1))
    else:
        ibm = reader.accessor(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
        if len(ibm) != len(joints):
            raise BadAvatarError(f"{path}: skin {skin_index} has {len(joints)} joints but {len(ibm)} inverse "
                                 "bind matrices")
    if not np.isfinite(ibm).all() or (np.abs(np.linalg.det(ibm[:, :3, :3])) < 1e-12).any():
        raise BadAvatarError(f"{path}: skin {skin_index} has singular or non-finite inverse bind matrices")

    local = np.stack([np.array(n.matrix, dtype=np.float64).reshape(4, 4).T if n.matrix is not None else
                      trs_matrix(n.translation or (0, 0, 0), n.rotation or (0, 0, 0, 1), n.scale or (1, 1, 1))
                      for n in nodes])
    order = _topological(parents)
    world = _world(local, parents, order)
    mesh_node = next(i for i in skinned if nodes[i].skin == skin_index)
    bind = world[mesh_node] @ affine_inverse(ibm)                  # B_k = M · IBM_k⁻¹
    size = max(float(np.ptp(bind[:, :3, 3], axis=0).max()), 1e-9)
    if np.abs(world[joints] - bind).max() > 1e-4 * size:
        # the nodes' rest pose is not the bind pose: rebuild the joints' locals from B_k, parents first
        is_joint = {int(n): k for k, n in enumerate(joints)}
        for i in order:
            if i in is_joint:
                p = parents[i]
                local[i] = bind[is_joint[i]] if p < 0 else affine_inverse(world[p]) @ bind[is_joint[i]]
            world[i] = local[i] if parents[i] < 0 else world[parents[i]] @ local[i]

    joint_of = {int(n): k for k, n in enumerate(joints)}
    joint_parents = np.full(len(joints), -1, dtype=np.int64)
    for k, n in enumerate(joints):
        p = parents[n]
        while p >= 0 and int(p) not in joint_of:
            p = parents[p]
        joint_parents[k] = joint_of[int(p)] if p >= 0 else -1
    names = tuple((nodes[n].name or "").strip() or f"joint{k}" for k, n in enumerate(joints))

    primitives = []
    for i in skinned:
        if nodes[i].skin != skin_index:
            continue
        mesh = doc.meshes[nodes[i].mesh]
        for pi, prim in enumerate(mesh.primitives):
            p = _primitive(path, doc, reader, i, nodes[i].mesh, pi, prim, len(joints))
            if p is not None:
                primitives.append(p)
    if not primitives:
        raise BadAvatarError(f"{path}: the skinned meshes have no triangle primitives with JOINTS_0/WEIGHTS_0")
    return Avatar(path, doc, blob, parents, local, world, joints, names, joint_parents, ibm, primitives,
                  _vrm_bones(doc, joint_of))


def _topological(parents: np.ndarray) -> list[int]:
    children = [[] for _ in parents]
    for c, p in enumerate(parents):
        if p >= 0:
            children[p].append(c)
    order, stack = [], [i for i, p in enumerate(parents) if p < 0]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(children[i])
    return order


def _world(local: np.ndarray, parents: np.ndarray, order: list[int]) -> np.ndarray:
    world = local.copy()
    for i in order:
        if parents[i] >= 0:
            world[i] = world[parents[i]] @ local[i]
    return world


def _primitive(path, doc, reader, node, mesh, index, prim, joint_count) -> Primitive | None:
    attrs = prim.attributes
    if prim.mode not in (None, 4) or attrs.POSITION is None or attrs.JOINTS_0 is None or attrs.WEIGHTS_0 is None:
        return None                                  # points, lines, strips, unskinned parts: not drawn by us
    pos = reader.accessor(attrs.POSITION).astype(np.float64)
    v = len(pos)
    where = f"{path}: mesh {mesh} primitive {index}"
    if pos.shape != (v, 3):
        raise BadAvatarError(f"{where}: POSITION must be VEC3")
    joints = reader.accessor(attrs.JOINTS_0)
    weights = reader.accessor(attrs.WEIGHTS_0).astype(np.float64)
    if joints.shape != (v, 4) or weights.shape != (v, 4):
        raise BadAvatarError(f"{where}: JOINTS_0/WEIGHTS_0 must be VEC4 per vertex")
    if (joints < 0).any() or (joints >= joint_count).any():
        raise BadAvatarError(f"{where}: JOINTS_0 names a joint outside the skin "
                             f"({joint_count} joints)")
    total = weights.sum(axis=1, keepdims=True)
    weights = np.where(total > 0, weights / np.where(total > 0, total, 1.0), np.eye(4)[0])
    indices = reader.accessor(prim.indices) if prim.indices is not None else np.arange(v)[:, None]
    if indices.shape[1:] != (1,) or len(indices) % 3 or indices.dtype.kind not in "iu":
        raise BadAvatarError(f"{where}: the indices must be integer triangles (a SCALAR count divisible by 3)")
    faces = indices[:, 0].reshape(-1, 3)
    if faces.size and (faces.min() < 0 or faces.max() >= v):
        raise BadAvatarError(f"{where}: an index points past its {v} vertices")
    normals = reader.accessor(attrs.NORMAL) if attrs.NORMAL is not None else _normals(pos, faces)
    uvs = reader.accessor(attrs.TEXCOORD_0) if attrs.TEXCOORD_0 is not None else None
    if normals.shape != (v, 3) or (uvs is not None and uvs.shape != (v, 2)):
        raise BadAvatarError(f"{where}: NORMAL must be VEC3 and TEXCOORD_0 VEC2 per vertex")
    color, image = np.array([0.8, 0.8, 0.8, 1.0]), None
    if prim.material is not None and doc.materials:
        pbr = doc.materials[prim.material].pbrMetallicRoughness
        if pbr is not None:
            color = np.array(pbr.baseColorFactor or [1, 1, 1, 1], dtype=np.float64)
            if pbr.baseColorTexture is not None and uvs is not None:
                image = _image(reader, pbr.baseColorTexture.index)
    return Primitive(node, mesh, index, pos, normals, joints, weights, faces.astype(np.int64), uvs, color, image)


def _normals(pos, faces):
    n = np.zeros_like(pos)
    tri = pos[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _image(reader: GltfDocument, texture_index):
    """The decoded base-colour image (PIL), or None if it cannot be read (the colour factor remains)."""
    from PIL import Image
    doc = reader.doc
    try:
        src = doc.images[doc.textures[texture_index].source]
        if src.bufferView is not None:
            data = reader.view(src.bufferView)
        elif src.uri and src.uri.startswith("data:"):
            import base64
            data = base64.b64decode(src.uri.split(",", 1)[1])
        else:
            return None
        return Image.open(io.BytesIO(data)).convert("RGB")
    except Exception:  # a broken texture must not stop the avatar: it is drawn in its colour factor
        return None


# VRM 0.x human bone names are camelCase ("leftUpperArm"); VRM 1.0 uses the same names.
_VRM_KEY = re.compile(r"^[a-zA-Z]+$")


def _vrm_bones(doc, joint_of: dict) -> dict:
    ext = doc.extensions or {}
    bones: dict[str, int] = {}
    vrm0 = (ext.get("VRM") or {}).get("humanoid", {}).get("humanBones")
    if isinstance(vrm0, list):
        for b in vrm0:
            if isinstance(b, dict) and isinstance(b.get("node"), int) and _VRM_KEY.match(str(b.get("bone", ""))):
                bones[b["bone"]] = b["node"]
    vrm1 = (ext.get("VRMC_vrm") or {}).get("humanoid", {}).get("humanBones")
    if isinstance(vrm1, dict):
        for name, b in vrm1.items():
            if isinstance(b, dict) and isinstance(b.get("node"), int):
                bones[name] = b["node"]
    return {name: joint_of[n] for name, n in bones.items() if n in joint_of}
