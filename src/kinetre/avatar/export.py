"""A retargeted take written out: the avatar's own file animated by its own joints (GLB/glTF), its
skeleton as BVH, or a rendered video.

glTF: the avatar's document is kept (meshes, materials, textures, skin, extensions); its own animations are
dropped and the buffer compacted to what remains; one animation is added with a rotation track per joint
(and a translation track where a joint travels: the armature's root, re-hung IK bones), keyed at every
frame. To be validator-clean and to play the same in every player, skinned-mesh nodes become scene roots
without transform (the glTF spec ignores their transform anyway, which three.js also does) and WEIGHTS_0 are
renormalised to sum 1 in float32. The joints' rest transforms are the bind pose (see load.py).
"""
from __future__ import annotations

import copy
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pygltflib as gl

from ..errors import ExportError
from ..export.gltf import append_accessor, rotation_quaternions, save_gltf, skin_weights
from .load import Avatar
from .retarget import AvatarMotion, RetargetPlan
from .skin import skin_avatar


def write_avatar_gltf(path, avatar: Avatar, motion: AvatarMotion, fps: float, name: str = "take",
                      morph_weights: dict | None = None) -> None:
    """Write the avatar animated by `motion` as .glb (or a single-file .gltf with an embedded buffer).

    `morph_weights` (mesh index -> (T, targets) weights in [0, 1], `ExpressionMap.weights`) adds a
    morph-weight track to every node showing that mesh.

    Raises
    ------
    ExportError
        Bad extension, empty or non-finite motion, unwritable path.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".glb", ".gltf"):
        raise ExportError(f"{path}: a glTF file must end in .glb or .gltf, got {ext or 'no extension'!r}")
    _check_motion(path, avatar, motion, fps)
    doc = gl.GLTF2.from_json(avatar.doc.to_json())
    shared = _detach_weights(doc, avatar)
    blob = _compact(doc, avatar.blob)
    _skinned_meshes_at_root(doc)
    _renormalised_weights(doc, blob, avatar, shared)

    n = len(avatar.joints)
    local = motion.local
    # rest TRS = bind pose; animation keys: rotation always, translation where the joint travels
    rest_t, rest_q, rest_s = _trs(avatar.rest_local[avatar.joints][None])
    anim_t, anim_q, _ = _trs(local)
    size = max(float(np.ptp(avatar.bind_positions, axis=0).max()), 1e-9)
    for j, node in enumerate(avatar.joints):
        nd = doc.nodes[node]
        nd.matrix = None
        nd.translation = [float(x) for x in rest_t[0, j]]
        nd.rotation = [float(x) for x in rest_q[0, j]]
        nd.scale = [float(x) for x in rest_s[0, j]]
    times = (np.arange(len(motion)) / fps).astype(np.float32)
    time_acc = append_accessor(doc, blob, times, gl.SCALAR, gl.FLOAT, minmax=True)
    samplers, channels = [], []
    for j in range(n):
        tracks = [("rotation", anim_q[:, j], gl.VEC4)]
        if np.abs(anim_t[:, j] - rest_t[0, j]).max() > 1e-7 * size:
            tracks.append(("translation", anim_t[:, j].astype(np.float32), gl.VEC3))
        for prop, values, kind in tracks:
            acc = append_accessor(doc, blob, np.ascontiguousarray(values, dtype=np.float32), kind, gl.FLOAT)
            samplers.append(gl.AnimationSampler(input=time_acc, output=acc, interpolation="LINEAR"))
            channels.append(gl.AnimationChannel(sampler=len(samplers) - 1,
                                                target=gl.AnimationChannelTarget(node=int(avatar.joints[j]), path=prop)))
    for mesh, weights in (morph_weights or {}).items():
        weights = np.asarray(weights, dtype=np.float32)
        targets = len(doc.meshes[mesh].primitives[0].targets or [])
        if weights.shape != (len(motion), targets) or not np.isfinite(weights).all():
            raise ExportError(f"{path}: mesh {mesh} needs ({len(motion)}, {targets}) finite morph weights, "
                              f"got {weights.shape}")
        acc = append_accessor(doc, blob, weights.reshape(-1), gl.SCALAR, gl.FLOAT)
        for node, nd in enumerate(doc.nodes):
            if nd.mesh == mesh:
                samplers.append(gl.AnimationSampler(input=time_acc, output=acc, interpolation="LINEAR"))
                channels.append(gl.AnimationChannel(sampler=len(samplers) - 1,
                                                    target=gl.AnimationChannelTarget(node=node, path="weights")))
    doc.animations = [gl.Animation(name=name, samplers=samplers, channels=channels)]
    save_gltf(path, doc, blob, "Kinetre (avatar retargeting, pygltflib)")


def write_avatar_bvh(path, avatar: Avatar, plan: RetargetPlan, motion: AvatarMotion, fps: float) -> None:
    """The avatar's skeleton (its joints, its kinematic hierarchy, bind-pose bone lengths) as BVH, one
    rotation per joint and frame plus the root's position, in the avatar's units."""
    from ..export.bvh import write_bvh
    from ..skeleton.models import Skeleton, SkeletonModel

    _check_motion(Path(path), avatar, motion, fps)
    names, seen = [], set()
    for name in avatar.joint_names:
        base = re.sub(r"[^A-Za-z0-9_.:-]+", "_", name) or "joint"
        unique, k = base, 2
        while unique in seen:
            unique, k = f"{base}_{k}", k + 1
        seen.add(unique)
        names.append(unique)
    model = SkeletonModel(f"avatar:{Path(avatar.source).stem}", tuple(names), tuple(int(p) for p in plan.parents))
    tracked = np.ones(len(names), dtype=bool)
    frames = [Skeleton(model, p, tracked) for p in motion.positions]
    # bones keep their lengths, so rotations alone (root-only positions) rebuild every joint
    write_bvh(path, frames, fps, joint_positions=False)


def write_avatar_video(path, avatar: Avatar, motion: AvatarMotion, fps: float, size=(640, 480), *,
                       on_frame=None) -> None:
    """Render the skinned avatar (its texture or material colours) per frame to .mp4/.webm."""
    from ..export.render import Camera, MeshRenderer
    from ..export.video import check_video_target, encode_video

    path = Path(path)
    width, height = check_video_target(path, size, fps, len(motion))
    _check_motion(path, avatar, motion, fps)
    prims = avatar.primitives
    offsets = np.cumsum([0] + [len(p.positions) for p in prims])
    faces = np.concatenate([p.faces + o for p, o in zip(prims, offsets)]).astype(np.int32)
    textured = [p for p in prims if p.image is not None]
    texture = textured[0].image if len(prims) == 1 and textured else None
    uvs = prims[0].uvs if texture is not None else None
    colors = np.concatenate([np.tile(_srgb(p.color if p.image is None or texture is not None else
                                           p.color * _mean_colour(p.image)), (len(p.positions), 1))
                             for p in prims])
    sample = motion.world[:: max(1, len(motion) // 24)]
    every = np.concatenate([np.concatenate(f) for f in skin_avatar(avatar, sample)])
    camera = Camera(every.min(axis=0), every.max(axis=0), (width, height))
    renderer = MeshRenderer(int(offsets[-1]), faces, camera, (width, height), uvs=uvs, colors=colors,
                            texture=texture)

    def frames():
        try:
            for k in range(len(motion)):
                pos, nrm = skin_avatar(avatar, motion.world[k:k + 1], normals=True)
                yield renderer.render(np.concatenate(pos[0]), np.concatenate(nrm[0]))
                if on_frame is not None:
                    on_frame(k)
        finally:
            renderer.release()

    encode_video(path, frames(), fps, (width, height))


def _srgb(linear_rgba):
    c = np.clip(np.asarray(linear_rgba, dtype=np.float64), 0, 1)
    return np.round(255 * np.r_[c[:3] ** (1 / 2.2), c[3]]).astype(np.uint8)


def _mean_colour(image):
    rgb = np.asarray(image.convert("RGB").resize((16, 16)), dtype=np.float64).reshape(-1, 3).mean(axis=0) / 255
    return np.r_[rgb ** 2.2, 1.0]


def _check_motion(path, avatar, motion, fps):
    if not len(motion):
        raise ExportError(f"{path}: the take has no frames to export")
    if not (np.isfinite(fps) and fps > 0):
        raise ExportError(f"{path}: fps must be a positive number, got {fps}")
    if motion.world.shape[1] != len(avatar.joints):
        raise ExportError(f"{path}: the motion has {motion.world.shape[1]} joints, the avatar {len(avatar.joints)}")
    if not (np.isfinite(motion.world).all() and np.isfinite(motion.local).all()):
        raise ExportError(f"{path}: the retargeted motion is not finite")


def _trs(matrices: np.ndarray):
    """(T, J, 4, 4) -> translations (T, J, 3), rotations (T, J, 4) x y z w (sign-continuous), scales."""
    t = matrices[..., :3, 3]
    lin = matrices[..., :3, :3]
    scale = np.linalg.norm(lin, axis=-2)
    det = np.sign(np.linalg.det(lin))
    scale[..., 0] *= np.where(det < 0, -1.0, 1.0)          # a mirrored joint: the mirror goes into scale x
    rot = lin / scale[..., None, :]
    f, n = rot.shape[:2]
    q = rotation_quaternions(rot.reshape(f, n, 3, 3))
    return t, q, scale


def _compact(doc, blob: bytes) -> bytearray:
    """Drop the animations and every accessor/bufferView only they used; return the rebuilt buffer."""
    doc.animations = []
    used_acc: list[int] = []

    def use(i):
        if i is not None and i not in used_acc:
            used_acc.append(i)
    for mesh in doc.meshes or []:
        for prim in mesh.primitives:
            for value in prim.attributes.__dict__.values():
                if isinstance(value, int):
                    use(value)
            use(prim.indices)
            for target in prim.targets or []:
                for value in (target.values() if isinstance(target, dict) else target.__dict__.values()):
                    if isinstance(value, int):
                        use(value)
    for skin in doc.skins or []:
        use(skin.inverseBindMatrices)
    acc_map = {old: new for new, old in enumerate(used_acc)}
    views: list[int] = []

    def view(i):
        if i is not None and i not in views:
            views.append(i)
    accessors = [copy.deepcopy(doc.accessors[i]) for i in used_acc]
    for a in accessors:
        view(a.bufferView)
        if a.sparse is not None:
            view(a.sparse.indices.bufferView)
            view(a.sparse.values.bufferView)
    for image in doc.images or []:
        view(image.bufferView)
    out = bytearray()
    new_views = []
    for i in views:
        bv = copy.deepcopy(doc.bufferViews[i])
        out.extend(b"\0" * (-len(out) % 8))
        start = bv.byteOffset or 0
        data = bytes(blob[start:start + bv.byteLength])
        bv.byteOffset, bv.buffer = len(out), 0
        out.extend(data)
        new_views.append(bv)
    view_map = {old: new for new, old in enumerate(views)}
    for a in accessors:
        if a.bufferView is not None:
            a.bufferView = view_map[a.bufferView]
        if a.sparse is not None:
            a.sparse.indices.bufferView = view_map[a.sparse.indices.bufferView]
            a.sparse.values.bufferView = view_map[a.sparse.values.bufferView]
    for image in doc.images or []:
        if image.bufferView is not None:
            image.bufferView = view_map[image.bufferView]
    for mesh in doc.meshes or []:
        for prim in mesh.primitives:
            for key, value in list(prim.attributes.__dict__.items()):
                if isinstance(value, int):
                    setattr(prim.attributes, key, acc_map[value])
            if prim.indices is not None:
                prim.indices = acc_map[prim.indices]
            for target in prim.targets or []:
                items = target.items() if isinstance(target, dict) else list(target.__dict__.items())
                for key, value in items:
                    if isinstance(value, int):
                        if isinstance(target, dict):
                            target[key] = acc_map[value]
                        else:
                            setattr(target, key, acc_map[value])
    for skin in doc.skins or []:
        if skin.inverseBindMatrices is not None:
            skin.inverseBindMatrices = acc_map[skin.inverseBindMatrices]
    doc.accessors, doc.bufferViews = accessors, new_views
    return out


def _skinned_meshes_at_root(doc) -> None:
    scene = doc.scenes[doc.scene or 0] if doc.scenes else None
    for i, node in enumerate(doc.nodes):
        if node.skin is None or node.mesh is None:
            continue
        for other in doc.nodes:
            if other.children and i in other.children:
                other.children = [c for c in other.children if c != i] or None
        node.matrix, node.translation, node.rotation, node.scale = None, None, None, None
        if scene is not None and i not in scene.nodes:
            scene.nodes.append(i)


def _detach_weights(doc, avatar: Avatar) -> list:
    """Unhook JOINTS_0/WEIGHTS_0 (rewritten below, so compaction drops the old ones); return, per primitive,
    the original accessor pair (primitives sharing one get one new pair)."""
    keys = []
    for p in avatar.primitives:
        attrs = doc.meshes[p.mesh].primitives[p.index].attributes
        keys.append((attrs.JOINTS_0, attrs.WEIGHTS_0))
        attrs.JOINTS_0 = attrs.WEIGHTS_0 = None
        for extra in ("JOINTS_1", "WEIGHTS_1"):        # influences past four: our LBS uses four, as three.js
            if hasattr(attrs, extra):
                setattr(attrs, extra, None)
    return keys


def _renormalised_weights(doc, blob: bytearray, avatar: Avatar, keys: list) -> None:
    """WEIGHTS_0 summing to 1 in float32 (and JOINTS_0 without repeats), one pair per original pair."""
    done: dict = {}
    for p, key in zip(avatar.primitives, keys):
        prim = doc.meshes[p.mesh].primitives[p.index]
        if key not in done:
            joints, weights = skin_weights(SimpleNamespace(vertex_weights=p.weights, vertex_nodes=p.joints,
                                                           node_count=len(avatar.joints)))
            joints[weights == 0] = 0                    # the validator wants unused slots on joint 0
            kind = gl.UNSIGNED_BYTE if joints.dtype == np.uint8 else gl.UNSIGNED_SHORT
            done[key] = (append_accessor(doc, blob, joints, gl.VEC4, kind, target=gl.ARRAY_BUFFER),
                         append_accessor(doc, blob, weights, gl.VEC4, gl.FLOAT, target=gl.ARRAY_BUFFER))
        prim.attributes.JOINTS_0, prim.attributes.WEIGHTS_0 = done[key]
