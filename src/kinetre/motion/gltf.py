"""Motion from a rigged glTF 2.0 file: one of its animations, evaluated per frame, as a `Take`.

The skeleton is the file's own joint hierarchy (the skins' joints, any number, any names; without a skin,
the animated nodes and their descendants). Per output frame every channel is sampled as glTF 2.0 §3.11
says (STEP, LINEAR with quaternion slerp on the shortest arc, CUBICSPLINE Hermite with the in/out
tangents scaled by the keyframe interval), each node's local matrix is T · R · S (or its `matrix`), and
world matrices run down the whole node hierarchy, non-joint parents included; a joint's position is the
translation of its world matrix. A joint's parent in the `SkeletonModel` is its nearest ancestor that is a
joint. Human skeletons are mapped to Kinect-20 by the skeleton mapper as BVH files are, unless `as_kinect=False`.

`path#NAME` or `path#INDEX` picks the animation (`split_animation`); without it, the first one.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import BadMotionError
from ..gltf_read import GltfDocument, read_gltf
from ..rotation import quaternion_matrices, rotation_part, slerp
from ..skeleton.models import SkeletonModel
from ..skeleton.humanoid_map import take_map
from ..skeleton.tips import part_end, part_tips
from .bvh import kinect_take, upright
from .take import Take

GLTF_EXTS = (".glb", ".gltf", ".vrma")
VRMA = "VRMC_vrm_animation"  # a VRM Animation's extension: humanoid bone name -> node
_PATHS = {"translation": 3, "rotation": 4, "scale": 3}
MAX_FRAMES = 1 << 21  # frames a take may have: over 19 hours at 30 fps


@dataclass(frozen=True)
class AnimationInfo:
    """One animation of a glTF file: its index, name, duration (s), channel count and the nodes it moves."""

    index: int
    name: str
    start: float
    end: float
    channels: int

    @property
    def duration(self) -> float:
        return self.end - self.start


def split_animation(ref: str | os.PathLike) -> tuple[str, str | None]:
    """"Fox.glb#Walk" -> ("Fox.glb", "Walk"); a path without a fragment -> (path, None).

    >>> split_animation("models/Fox.glb#1")
    ('models/Fox.glb', '1')
    >>> split_animation("walk.bvh")
    ('walk.bvh', None)
    """
    ref = os.fspath(ref)
    head, sep, frag = ref.rpartition("#")
    if sep and head.lower().endswith(GLTF_EXTS):
        return head, frag
    return ref, None


def is_gltf(ref: str | os.PathLike) -> bool:
    return split_animation(ref)[0].lower().endswith(GLTF_EXTS)


def animations(path: str | os.PathLike | GltfDocument) -> list[AnimationInfo]:
    """The animations of a glTF file (empty when it has none); a loaded `GltfDocument` is not parsed again
    (pygltflib's JSON decoding is most of the cost of reading a small file)."""
    d = path if isinstance(path, GltfDocument) else read_gltf(path, BadMotionError)
    out = []
    for i, anim in enumerate(d.doc.animations or []):
        times = [d.accessor(anim.samplers[c.sampler].input) for c in anim.channels]
        start = min((float(t.min()) for t in times if t.size), default=0.0)
        end = max((float(t.max()) for t in times if t.size), default=0.0)
        out.append(AnimationInfo(i, anim.name or f"animation {i}", start, end, len(anim.channels)))
    return out


def _pick(infos: list[AnimationInfo], which: str | int | None, path: str) -> AnimationInfo:
    listing = ", ".join(f"{a.index} {a.name!r}" for a in infos)
    if not infos:
        raise BadMotionError(f"{path}: the file has no animations")
    if which is None or which == "":
        return infos[0]
    text = str(which)
    for a in infos:
        if a.name == text:
            return a
    if text.lstrip("-").isdigit():
        i = int(text)
        if 0 <= i < len(infos):
            return infos[i]
        raise BadMotionError(f"{path}: no animation #{i} (it has {len(infos)}: {listing})")
    raise BadMotionError(f"{path}: no animation named {text!r} (available: {listing})")


# ---- the sampler (glTF 2.0 §3.11, Appendix C) -------------------------------------------------------

def sample(times: np.ndarray, values: np.ndarray, interpolation: str, t: np.ndarray,
           rotation: bool = False) -> np.ndarray:
    """Evaluate one animation sampler at times t (F,): (F, n).

    Parameters
    ----------
    times : (K,) float, strictly increasing keyframe times (seconds)
    values : (K, n) float, or (3K, n) for CUBICSPLINE (in-tangent, value, out-tangent per key)
    interpolation : "STEP", "LINEAR" or "CUBICSPLINE"
    rotation : the values are unit quaternions (x, y, z, w): LINEAR slerps, the others renormalise

    Before the first key the first value holds, after the last the last one (the spec's clamping).

    >>> sample(np.array([0.0, 1.0]), np.array([[0.0], [2.0]]), "LINEAR", np.array([-1.0, 0.25, 3.0]))
    array([[0. ],
           [0.5],
           [2. ]])
    """
    times = np.asarray(times, dtype=np.float64).ravel()
    values = np.asarray(values, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).ravel()
    cubic = interpolation == "CUBICSPLINE"
    if cubic:
        a_in, v, b_out = values[0::3], values[1::3], values[2::3]
    else:
        v = values
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
    k1 = np.minimum(k + 1, len(times) - 1)
    dt = times[k1] - times[k]
    u = np.where(dt > 0, (t - times[k]) / np.where(dt > 0, dt, 1.0), 0.0)
    u = np.clip(u, 0.0, 1.0)
    if interpolation == "STEP":
        out = v[k]
    elif cubic:
        u2, u3 = u * u, u * u * u
        h00, h10 = 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u
        h01, h11 = -2 * u3 + 3 * u2, u3 - u2
        out = (h00[:, None] * v[k] + (h10 * dt)[:, None] * b_out[k] + h01[:, None] * v[k1]
               + (h11 * dt)[:, None] * a_in[k1])
    elif rotation:
        return slerp(v[k], v[k1], u)
    else:
        out = (1 - u)[:, None] * v[k] + u[:, None] * v[k1]
    if rotation:
        out = out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
    return out


# ---- hierarchy ---------------------------------------------------------------------------------------

def _node_order(doc, path: str) -> tuple[list[int], dict[int, int]]:
    """Nodes parents-first (depth first from the roots) and each node's parent."""
    parent: dict[int, int] = {}
    for i, n in enumerate(doc.nodes):
        for c in n.children or []:
            if c in parent or not 0 <= c < len(doc.nodes) or c == i:
                raise BadMotionError(f"{path}: node {c} has two parents or is out of range (not a tree)")
            parent[c] = i
    order, seen = [], set()
    stack = [i for i in reversed(range(len(doc.nodes))) if i not in parent]
    while stack:
        i = stack.pop()
        if i in seen:
            raise BadMotionError(f"{path}: the node hierarchy has a cycle at node {i}")
        seen.add(i)
        order.append(i)
        stack.extend(reversed(doc.nodes[i].children or []))
    if len(order) != len(doc.nodes):
        raise BadMotionError(f"{path}: the node hierarchy has a cycle")
    return order, parent


def world_matrices(d: GltfDocument, anim_index: int | None, t: np.ndarray) -> np.ndarray:
    """(F, N, 4, 4) world matrix of every node at times t (F,), animated by animation `anim_index`."""
    doc = d.doc
    f, n = len(t), len(doc.nodes)
    trs = []
    for node in doc.nodes:
        trs.append([np.tile(np.array(node.translation if node.translation is not None else [0, 0, 0], float), (f, 1)),
                    np.tile(np.array(node.rotation if node.rotation is not None else [0, 0, 0, 1], float), (f, 1)),
                    np.tile(np.array(node.scale if node.scale is not None else [1, 1, 1], float), (f, 1))])
    animated = set()
    if anim_index is not None:
        anim = doc.animations[anim_index]
        for c in anim.channels:
            target = c.target
            if target is None or target.node is None or target.path not in _PATHS:
                continue  # morph-target weights and extension targets move no joint
            s = anim.samplers[c.sampler]
            times = d.accessor(s.input)[:, 0]
            values = d.accessor(s.output)
            width = _PATHS[target.path]
            interp = s.interpolation or "LINEAR"
            need = len(times) * (3 if interp == "CUBICSPLINE" else 1)
            if values.shape != (need, width) or interp not in ("STEP", "LINEAR", "CUBICSPLINE") or \
                    len(times) == 0 or np.any(np.diff(times) <= 0):
                raise BadMotionError(f"{d.path}: animation {anim_index} channel on node {target.node} "
                                     f"({target.path}) has a malformed sampler")
            slot = ("translation", "rotation", "scale").index(target.path)
            trs[target.node][slot] = sample(times, values, interp, t, target.path == "rotation")
            animated.add(target.node)
    order, parent = _node_order(doc, d.path)
    world = np.zeros((f, n, 4, 4))
    for i in order:
        node = doc.nodes[i]
        if node.matrix is not None and i not in animated:
            local = np.broadcast_to(np.array(node.matrix, float).reshape(4, 4).T, (f, 4, 4))
        else:
            tr, q, sc = trs[i]
            local = np.zeros((f, 4, 4))
            local[:, :3, :3] = quaternion_matrices(q) * sc[:, None, :]
            local[:, :3, 3] = tr
            local[:, 3, 3] = 1.0
        world[:, i] = local if i not in parent else world[:, parent[i]] @ local
    return world


def skin_weights(d: GltfDocument) -> dict[int, float]:
    """Total skin weight per joint node over the skinned meshes (empty when no mesh is skinned)."""
    doc, total = d.doc, {}
    for node in doc.nodes:
        if node.mesh is None or node.skin is None:
            continue
        joints = doc.skins[node.skin].joints or []
        for prim in doc.meshes[node.mesh].primitives:
            attrs = prim.attributes
            if getattr(attrs, "JOINTS_0", None) is None or getattr(attrs, "WEIGHTS_0", None) is None:
                continue
            idx = d.accessor(attrs.JOINTS_0).astype(np.int64)
            w = d.accessor(attrs.WEIGHTS_0)
            if idx.shape != w.shape or idx.size and (idx.min() < 0 or idx.max() >= len(joints)):
                raise BadMotionError(f"{d.path}: a skinned primitive's JOINTS_0 does not fit its skin")
            sums = np.bincount(idx.ravel(), weights=w.ravel(), minlength=len(joints))
            for j, s in zip(joints, sums):
                total[j] = total.get(j, 0.0) + float(s)
    return total


def skin_centroids(d: GltfDocument) -> dict[int, np.ndarray]:
    """Per joint node, the skin-weighted mean of the vertices it moves, in its own bind frame (inverse bind
    matrix times vertex): where the part it carries lies (empty when no mesh is skinned)."""
    return {j: c for j, (c, _) in _skin_parts(d).items()}


def skin_ends(d: GltfDocument) -> dict[int, np.ndarray]:
    """Per joint node, where the part it carries ends, in its own bind frame: from the joint towards the
    part's centre (`skin_centroids`), as far as the vertices it mostly moves reach (`part_end`)."""
    return {j: part_end(c, v) for j, (c, v) in _skin_parts(d).items()}


def _skin_parts(d: GltfDocument) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per joint node: (weighted centre, the vertices it mostly moves (weight >= 1/2)), in its bind frame."""
    doc, sums, mass, mostly = d.doc, {}, {}, {}
    for node in doc.nodes:
        if node.mesh is None or node.skin is None:
            continue
        skin = doc.skins[node.skin]
        joints = skin.joints or []
        ibm = np.tile(np.eye(4), (len(joints), 1, 1)) if skin.inverseBindMatrices is None else \
            d.accessor(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
        if len(ibm) != len(joints):
            raise BadMotionError(f"{d.path}: skin {node.skin} has {len(ibm)} inverse bind matrices for "
                                 f"{len(joints)} joints")
        for prim in doc.meshes[node.mesh].primitives:
            attrs = prim.attributes
            if getattr(attrs, "JOINTS_0", None) is None or getattr(attrs, "WEIGHTS_0", None) is None:
                continue
            idx = d.accessor(attrs.JOINTS_0).astype(np.int64)
            w = d.accessor(attrs.WEIGHTS_0).astype(np.float64)
            v = d.accessor(attrs.POSITION).astype(np.float64)
            if idx.shape != w.shape or len(v) != len(idx) or idx.size and (idx.min() < 0 or idx.max() >= len(joints)):
                raise BadMotionError(f"{d.path}: a skinned primitive's JOINTS_0 does not fit its skin")
            local = np.einsum("vkab,vb->vka", ibm[idx][..., :3, :3], v) + ibm[idx][..., :3, 3]
            total = np.maximum(w.sum(axis=1, keepdims=True), 1e-12)
            for k, j in enumerate(joints):
                hit = idx == k
                if not (w * hit).sum() > 0:
                    continue
                sums[j] = sums.get(j, 0.0) + (w[..., None] * hit[..., None] * local).sum(axis=(0, 1))
                mass[j] = mass.get(j, 0.0) + float((w * hit).sum())
                most = (w * hit / total >= 0.5).any(axis=1)
                mostly.setdefault(j, []).append(local[most][hit[most]])
    return {j: (sums[j] / mass[j], np.concatenate(mostly[j]) if j in mostly else np.zeros((0, 3))) for j in sums}


def skeleton_nodes(d: GltfDocument, anim_index: int | None,
                   handles: bool = False) -> tuple[list[int], tuple[int, ...]]:
    """The joint nodes (parents first) and each one's parent joint (nearest joint ancestor, -1 for none).

    Joints are the union of the skins' joints; a file without skins uses the animated nodes and everything
    below them. Unless `handles`, handles above the body are left out: joints that move no vertex and have
    no ancestor that does, but have descendants that do (Fox's `_rootJoint` on the ground): their bone to the
    hips would otherwise pull on the belly. The skeleton mapper keeps them: such a joint may be where the
    legs branch (as for avatars, which map all their skin joints).
    """
    doc = d.doc
    order, parent = _node_order(doc, d.path)
    joints = {j for s in doc.skins or [] for j in s.joints or []}
    if not joints and anim_index is not None:
        # a VRM Animation's expression nodes carry face weights, not bones
        faces = {e.get("node") for group in (_vrma(d).get("expressions") or {}).values() if isinstance(group, dict)
                 for e in group.values() if isinstance(e, dict)}
        targets = {c.target.node for c in doc.animations[anim_index].channels
                   if c.target is not None and c.target.node is not None and c.target.node not in faces}
        for i in order:
            if i in targets or parent.get(i) in joints:
                joints.add(i)
    weight = {} if handles else skin_weights(d)
    if weight:
        moved_below: dict[int, bool] = {}
        for i in reversed(order):  # children before parents
            moved_below[i] = any(weight.get(c, 0.0) > 0 or moved_below[c] for c in doc.nodes[i].children or [])
        for i in order:
            chain, p = [i], parent.get(i)
            while p is not None:
                chain.append(p)
                p = parent.get(p)
            if i in joints and moved_below[i] and all(weight.get(a, 0.0) <= 0 for a in chain):
                joints.discard(i)
    nodes = [i for i in order if i in joints]
    if len(nodes) < 2:
        raise BadMotionError(f"{d.path}: no skeleton (the file has {len(nodes)} joint node(s); need at least 2)")
    index = {j: k for k, j in enumerate(nodes)}
    parents = []
    for j in nodes:
        p = parent.get(j)
        while p is not None and p not in index:
            p = parent.get(p)
        parents.append(-1 if p is None else index[p])
    return nodes, tuple(parents)


def node_names(doc, nodes: list[int]) -> tuple[str, ...]:
    """The names a take gives glTF joint nodes: the node's name, "node<index>" without one, made unique."""
    names, seen = [], set()
    for j in nodes:
        base = doc.nodes[j].name or f"node{j}"
        name, k = base, 2
        while name in seen:  # a SkeletonModel needs unique names
            name, k = f"{base}.{k}", k + 1
        seen.add(name)
        names.append(name)
    return tuple(names)


def _skeleton(d: GltfDocument, index: int, handles: bool = False):
    nodes, parents = skeleton_nodes(d, index, handles)
    rest = world_matrices(d, None, np.zeros(1))[0, nodes][:, :3, 3]
    return nodes, node_names(d.doc, nodes), parents, rest


def animation_skeleton(path: str | os.PathLike, animation: str | int | None = None):
    """(names, parents, rest positions (J, 3), tips) of the skeleton one animation moves ("file.glb#NAME"
    or `animation`; default the first), handles included, its last `tips` joints the part tips
    (`kinetre.skeleton.tips`): what `load_gltf` maps to Kinect-20."""
    path, frag = split_animation(path)
    d = read_gltf(path, BadMotionError)
    info = _pick(animations(d), frag if animation is None else animation, path)
    return _mapped_skeleton(d, info.index)


def animation_vrm_bones(path: str | os.PathLike, animation: str | int | None = None) -> dict:
    """VRM humanoid bone name -> joint index of `animation_skeleton`'s skeleton (a VRM Animation's; else {})."""
    path, frag = split_animation(path)
    d = read_gltf(path, BadMotionError)
    info = _pick(animations(d), frag if animation is None else animation, path)
    return vrm_bones(d, skeleton_nodes(d, info.index, handles=True)[0])


def vrm_bones(d: GltfDocument, nodes: list[int]) -> dict:
    """VRM humanoid bone name -> joint index, from a VRM Animation's `VRMC_vrm_animation.humanoid` (empty
    for other files)."""
    bones = (_vrma(d).get("humanoid") or {}).get("humanBones") or {}
    index = {j: k for k, j in enumerate(nodes)}
    return {b: index[v["node"]] for b, v in bones.items() if isinstance(v, dict) and v.get("node") in index}


def _vrma(d: GltfDocument) -> dict:
    ext = (d.doc.extensions or {}).get(VRMA)
    return ext if isinstance(ext, dict) else {}


def _mapped_skeleton(d: GltfDocument, index: int):
    nodes, names, parents, rest = _skeleton(d, index, handles=True)
    ends = _tips(d, nodes, parents, names)
    if not ends:
        return names, parents, rest, 0
    world = world_matrices(d, None, np.zeros(1))[0]
    local = skin_ends(d)
    tips = np.array([world[nodes[k], :3, :3] @ local[nodes[k]] + world[nodes[k], :3, 3] for k, _ in ends])
    return (names + tuple(n for _, n in ends), parents + tuple(k for k, _ in ends), np.vstack([rest, tips]),
            len(ends))


def load_gltf(path: str | os.PathLike, animation: str | int | None = None, fps: float = 30.0,
              as_kinect: bool = True) -> Take:
    """One animation of a glTF/GLB file as a `Take` (the file's units, which glTF defines as metres).

    Parameters
    ----------
    path : "file.glb", or "file.glb#NAME" / "file.glb#INDEX" (the fragment picks the animation when
        `animation` is None)
    animation : name or index of the animation; default the first
    fps : frames per second to sample the animation at (frame i at start + i / fps; the last key is
        included when the duration is a whole number of frames)
    as_kinect : map a human skeleton to Kinect-20 (as `load_bvh`); False keeps the file's own hierarchy

    Raises
    ------
    BadMotionError
        Missing or corrupt file, no animations, an unknown animation name or index (the message lists
        the available ones), fewer than two joints, a malformed sampler.
    """
    path, frag = split_animation(path)
    if animation is None:
        animation = frag
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise BadMotionError(f"{path}: fps must be a positive number, got {fps!r}")
    d = read_gltf(path, BadMotionError)
    info = _pick(animations(d), animation, path)
    if not info.duration * fps < MAX_FRAMES:  # a bent keyframe time would ask for billions of frames
        raise BadMotionError(f"{path}: animation {info.name!r} lasts {info.duration:.4g} s, over {MAX_FRAMES} "
                             f"frames at {fps:g} fps")
    count = int(math.floor(info.duration * fps + 1e-6)) + 1
    t = info.start + np.arange(count) / fps
    world = world_matrices(d, info.index, t)
    source = f"{path}#{info.name}"
    own = _own_take(d, info.index, world, float(fps), source)
    if as_kinect:
        names, parents, rest, tips = _mapped_skeleton(d, info.index)
        vrm = vrm_bones(d, skeleton_nodes(d, info.index, handles=True)[0])
        hmap = take_map(names, parents, rest, tips=tips, vrm=vrm or None)
        if hmap is not None:
            mapped = _own_take(d, info.index, world, float(fps), source, handles=True, tips="end" if tips else "")
            turn = upright(hmap, rest)
            take = kinect_take(hmap, mapped, turn, native=own)
            if "hips" in vrm:
                take = replace(take, hips_turns=_hips_turns(d, world, skeleton_nodes(d, info.index, True)[0],
                                                            vrm["hips"], turn))
            return take
    return own


def _hips_turns(d: GltfDocument, world: np.ndarray, nodes: list[int], hips: int, turn: np.ndarray) -> np.ndarray:
    """(T, 3, 3) a VRM Animation's hips rotation from its rest pose (the T-pose the format defines), in the
    take's frame: three-vrm plays the hips by the same relative turn."""
    node = nodes[hips]
    rest = rotation_part(world_matrices(d, None, np.zeros(1))[0, node, :3, :3])
    now = rotation_part(world[:, node, :3, :3])
    return turn @ now @ rest.T @ turn.T


def _own_take(d: GltfDocument, index: int, world: np.ndarray, fps: float, source: str, handles: bool = False,
              tips: str = "centre") -> Take:
    """The file's own skeleton as a take, with its bone frames and tips: at the parts' centres ("centre"),
    where they end ("end", as the skeleton mapper reads them) or none ("")."""
    nodes, names, parents, _ = _skeleton(d, index, handles)
    positions = world[:, nodes][..., :3, 3]
    # a joint is carried by its parent node's frame (a non-joint node in between included)
    node_parent = _node_order(d.doc, d.path)[1]
    carriers = [node_parent.get(j, j) for j in nodes]
    # a last joint (a head, a hand without fingers) turns the part it carries, which no bone of the
    # joints shows: a tip joint at that part's skinned centre, carried by the last joint, makes it a bone
    ends = _tips(d, nodes, parents, names) if tips else []
    if ends:
        centres = skin_centroids(d) if tips == "centre" else skin_ends(d)
        local = np.array([np.append(centres[nodes[k]], 1.0) for k, _ in ends])
        tip_world = np.einsum("fkab,kb->fka", world[:, [nodes[k] for k, _ in ends]][..., :3, :], local)
        positions = np.concatenate([positions, tip_world], axis=1)
        carriers = carriers + [nodes[k] for k, _ in ends]
        names, parents = names + tuple(n for _, n in ends), parents + tuple(k for k, _ in ends)
    weight = skin_weights(d)
    # a joint that moves none of its file's skin is a helper: the artist's skin does not turn with it
    unskinned = tuple(n for n, j in zip(names, nodes) if weight.get(j, 0.0) <= 0.0) if weight else ()
    model = SkeletonModel(f"gltf:{Path(d.path).stem}", names, parents, unskinned)
    return Take(model, positions, np.ones(positions.shape[:2], dtype=bool), fps, source,
                bone_frames=rotation_part(world[:, carriers][..., :3, :3]))


def _tips(d: GltfDocument, nodes: list[int], parents: tuple[int, ...], names: tuple[str, ...]) -> list[tuple[int, str]]:
    """(joint index, tip name) of `kinetre.skeleton.tips.part_tips` on the file's rest pose."""
    world = world_matrices(d, None, np.zeros(1))[0]
    local = skin_centroids(d)
    centres = {k: world[j, :3, :3] @ local[j] + world[j, :3, 3] for k, j in enumerate(nodes) if j in local}
    return [(k, name) for k, name, _ in part_tips(names, parents, world[nodes][:, :3, 3], centres)]
