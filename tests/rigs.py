"""Synthetic rigged characters with a known animation, written as GLB: the rigs game packs and creature
packs ship and the shared avatars lack.

* `seven_joint_figure`: a root, a torso, a head and one bone per arm and per leg (Kenney style), the body
  and the head as two meshes with their own skins;
* `chibi`: root / body_low / body_up / head, hip + leg per side, hands hanging straight off the chest, and
  sockets (attachment points no vertex follows);
* `rigid_robot`: a full humanoid whose every part is a separate piece bound fully to one bone;
* `legged_creature`: a body carried by any number of three-bone legs reaching the floor, walking in two
  alternating groups.

Every rig faces +Z, +Y up, its left on +X, and stands on y = 0. The animation is keyed at 30 fps (rotations
per joint, the root's translation); `write_glb` writes it with pygltflib.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pygltflib as gl
import trimesh

FPS = 30.0


@dataclass
class Rig:
    """names, parents (J,), rest (J, 3) world joint positions in the bind pose (joints unrotated), parts: one
    glTF mesh each (vertices, faces, joints (V, 4), weights (V, 4)), and the animation: rotations (T, J, 4)
    local quaternions xyzw, translation (T, 3) of the first root."""

    names: list = field(default_factory=list)
    parents: list = field(default_factory=list)
    rest: list = field(default_factory=list)
    parts: list = field(default_factory=list)
    rotations: np.ndarray | None = None
    translation: np.ndarray | None = None

    def add(self, name: str, parent: str | None, p) -> int:
        self.names.append(name)
        self.parents.append(self.names.index(parent) if parent else -1)
        self.rest.append(np.asarray(p, dtype=np.float64))
        return len(self.names) - 1

    def j(self, name: str) -> int:
        return self.names.index(name)

    def part(self, pieces) -> None:
        """One mesh of (trimesh, joints (V, 4) or joint index, weights (V, 4) or None) pieces."""
        verts, faces, joints, weights = [], [], [], []
        n = 0
        for mesh, jt, wt in pieces:
            v = np.asarray(mesh.vertices)
            if np.isscalar(jt):
                jt, wt = np.tile([jt, 0, 0, 0], (len(v), 1)), np.tile([1.0, 0, 0, 0], (len(v), 1))
            verts.append(v)
            faces.append(np.asarray(mesh.faces) + n)
            joints.append(jt)
            weights.append(wt)
            n += len(v)
        self.parts.append((np.concatenate(verts), np.concatenate(faces), np.concatenate(joints),
                           np.concatenate(weights)))

    def still(self, frames: int) -> None:
        self.rotations = np.tile([0.0, 0.0, 0.0, 1.0], (frames, len(self.names), 1))
        root = self.parents.index(-1)
        self.translation = np.tile(self.rest[root], (frames, 1))


def capsule(a, b, radius: float, count=(10, 10)) -> trimesh.Trimesh:
    """A capsule around the segment a -> b."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    length = float(np.linalg.norm(b - a))
    cap = trimesh.creation.capsule(height=max(length, 1e-6), radius=radius, count=list(count))
    z = (b - a) / max(length, 1e-12)
    x = np.cross(z, [0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.cross(z, [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    m = np.eye(4)
    m[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    m[:3, 3] = 0.5 * (a + b)
    cap.apply_transform(m)
    return cap


def sphere(c, radius: float, scale=(1.0, 1.0, 1.0)) -> trimesh.Trimesh:
    s = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    s.vertices = s.vertices * np.asarray(scale) + np.asarray(c, dtype=np.float64)
    return s


def blended(mesh: trimesh.Trimesh, a, b, inner: int, outer: int, blend: float = 0.25):
    """(mesh, joints, weights): vertices along a -> b belong to `outer`, blending into `inner` over the
    first `blend` of the way (a smooth skin about the joint at a)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    d = b - a
    t = np.clip((np.asarray(mesh.vertices) - a) @ d / (d @ d), 0.0, 1.0)
    w = np.clip(0.5 + t / (2 * blend), 0.5, 1.0) if blend > 0 else np.ones_like(t)
    joints = np.zeros((len(t), 4), dtype=np.int64)
    joints[:, 0], joints[:, 1] = outer, inner
    weights = np.zeros((len(t), 4))
    weights[:, 0], weights[:, 1] = w, 1.0 - w
    return mesh, joints, weights


def quat(axis, angle) -> np.ndarray:
    """(..., 4) xyzw quaternions about a fixed axis by angles (...,)."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    angle = np.asarray(angle, dtype=np.float64)
    return np.concatenate([np.sin(angle / 2)[..., None] * axis, np.cos(angle / 2)[..., None]], axis=-1)


def qmul(a, b) -> np.ndarray:
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def _phase(frames: int, cycles: float = 1.0) -> np.ndarray:
    return 2 * np.pi * cycles * np.arange(frames) / max(frames - 1, 1)


def seven_joint_figure(frames: int = 40) -> Rig:
    """Root, torso, head, one bone per arm and leg (arms hanging in an A-pose), walking forward."""
    r = Rig()
    r.add("root", None, (0, 0, 0))
    r.add("torso", "root", (0, 0.5, 0))
    r.add("head", "torso", (0, 0.8, 0))
    for side, x in (("left", 1.0), ("right", -1.0)):
        r.add(f"arm-{side}", "torso", (0.13 * x, 0.77, 0))
        r.add(f"leg-{side}", "torso", (0.07 * x, 0.48, 0))
    body = [blended(capsule((0, 0.45, 0), (0, 0.78, 0), 0.1), (0, 0.45, 0), (0, 0.78, 0), r.j("root"),
                    r.j("torso"), 0.0)]
    for side, x in (("left", 1.0), ("right", -1.0)):
        sh, wr = np.array([0.13 * x, 0.77, 0]), np.array([0.24 * x, 0.47, 0])
        body.append(blended(capsule(sh, wr, 0.035), sh, wr, r.j("torso"), r.j(f"arm-{side}"), 0.15))
        hp, an = np.array([0.07 * x, 0.48, 0]), np.array([0.07 * x, 0.04, 0])
        body.append(blended(capsule(hp, an, 0.045), hp, an, r.j("torso"), r.j(f"leg-{side}"), 0.1))
        body.append((capsule(an, an + [0, 0, 0.08], 0.04), r.j(f"leg-{side}"), None))
    r.part(body)
    r.part([(sphere((0, 0.9, 0), 0.1), r.j("head"), None)])
    r.still(frames)
    ph = _phase(frames)
    swing = 0.45 * np.sin(ph)
    r.rotations[:, r.j("leg-left")] = quat([1, 0, 0], -swing)
    r.rotations[:, r.j("leg-right")] = quat([1, 0, 0], swing)
    r.rotations[:, r.j("arm-left")] = qmul(quat([0, 0, 1], 0.15 * np.ones(frames)), quat([1, 0, 0], 0.5 * swing))
    r.rotations[:, r.j("arm-right")] = qmul(quat([0, 0, 1], -0.15 * np.ones(frames)), quat([1, 0, 0], -0.5 * swing))
    r.rotations[:, r.j("torso")] = quat([0, 1, 0], 0.12 * np.sin(ph))
    r.rotations[:, r.j("head")] = quat([1, 0, 0], 0.15 * np.sin(2 * ph))
    r.translation[:, 2] = 0.5 * np.arange(frames) / FPS
    r.translation[:, 1] = -0.015 * (1 - np.cos(2 * ph))
    return r


def chibi(frames: int = 40) -> Rig:
    """A big-headed chibi: root on the floor, body_low / body_up, hip + leg per side, the hands hanging off
    body_up without arm bones, and sockets for props."""
    r = Rig()
    r.add("root", None, (0, 0, 0))
    r.add("body_low", "root", (0, 0.3, 0))
    r.add("body_up", "body_low", (0, 0.45, 0))
    r.add("head", "body_up", (0, 0.58, 0))
    r.add("socket_head", "head", (0, 1.0, 0))
    for s, x in (("L", 1.0), ("R", -1.0)):
        r.add(f"hip_{s}", "body_low", (0.07 * x, 0.3, 0))
        r.add(f"leg_{s}", f"hip_{s}", (0.07 * x, 0.16, 0))
        r.add(f"hand_{s}", "body_up", (0.14 * x, 0.5, 0))
        r.add(f"socket_hand_{s}", f"hand_{s}", (0.2 * x, 0.3, 0.03))
    body = [blended(capsule((0, 0.28, 0), (0, 0.55, 0), 0.11), (0, 0.3, 0), (0, 0.55, 0), r.j("body_low"),
                    r.j("body_up"), 0.5)]
    for s, x in (("L", 1.0), ("R", -1.0)):
        hp, kn, an = np.array([0.07 * x, 0.3, 0]), np.array([0.07 * x, 0.16, 0]), np.array([0.07 * x, 0.04, 0])
        body.append(blended(capsule(hp, kn, 0.045), hp, kn, r.j("body_low"), r.j(f"hip_{s}"), 0.2))
        body.append(blended(capsule(kn, an, 0.04), kn, an, r.j(f"hip_{s}"), r.j(f"leg_{s}"), 0.3))
        body.append((sphere(an + [0, 0, 0.03], 0.05, (1.0, 0.6, 1.4)), r.j(f"leg_{s}"), None))
        body.append((sphere((0.19 * x, 0.33, 0.0), 0.055), r.j(f"hand_{s}"), None))
    r.part(body)
    r.part([(sphere((0, 0.78, 0), 0.21), r.j("head"), None)])
    r.still(frames)
    ph = _phase(frames)
    swing = 0.5 * np.sin(ph)
    for s, k in (("L", 1.0), ("R", -1.0)):
        r.rotations[:, r.j(f"hip_{s}")] = quat([1, 0, 0], -k * swing)
        r.rotations[:, r.j(f"leg_{s}")] = quat([1, 0, 0], 0.5 * (1 + np.sin(ph + k * np.pi / 2)))
        r.rotations[:, r.j(f"hand_{s}")] = quat([1, 0, 0], 0.6 * k * swing)
    r.rotations[:, r.j("body_up")] = quat([0, 1, 0], 0.15 * np.sin(ph))
    r.rotations[:, r.j("head")] = quat([0, 0, 1], 0.15 * np.sin(ph))
    r.translation[:, 2] = 0.3 * np.arange(frames) / FPS
    return r


def rigid_robot(frames: int = 40) -> Rig:
    """A humanoid of separate parts (Mixamo-named bones), each part bound fully to one bone, waving and
    stepping."""
    r = Rig()
    r.add("Hips", None, (0, 0.95, 0))
    r.add("Spine", "Hips", (0, 1.1, 0))
    r.add("Neck", "Spine", (0, 1.45, 0))
    r.add("Head", "Neck", (0, 1.55, 0))
    parts = [(capsule((0, 0.9, 0), (0, 1.05, 0), 0.12), r.j("Hips"), None),
             (sphere((0, 1.28, 0), 0.17, (1.0, 1.1, 0.7)), r.j("Spine"), None),
             (capsule((0, 1.45, 0), (0, 1.52, 0), 0.04), r.j("Neck"), None),
             (sphere((0, 1.66, 0), 0.11), r.j("Head"), None)]
    for side, x in (("Left", 1.0), ("Right", -1.0)):
        sh, el, wr = (0.2 * x, 1.42, 0), (0.44 * x, 1.42, 0), (0.66 * x, 1.42, 0)
        r.add(f"{side}Arm", "Spine", sh)
        r.add(f"{side}ForeArm", f"{side}Arm", el)
        r.add(f"{side}Hand", f"{side}ForeArm", wr)
        hp, kn, an = (0.1 * x, 0.9, 0), (0.1 * x, 0.5, 0), (0.1 * x, 0.08, 0)
        r.add(f"{side}UpLeg", "Hips", hp)
        r.add(f"{side}Leg", f"{side}UpLeg", kn)
        r.add(f"{side}Foot", f"{side}Leg", an)
        parts += [(capsule(np.add(sh, (0.03 * x, 0, 0)), np.add(el, (-0.02 * x, 0, 0)), 0.045), r.j(f"{side}Arm"), None),
                  (capsule(np.add(el, (0.02 * x, 0, 0)), np.add(wr, (-0.02 * x, 0, 0)), 0.04), r.j(f"{side}ForeArm"), None),
                  (sphere(np.add(wr, (0.05 * x, 0, 0)), 0.045), r.j(f"{side}Hand"), None),
                  (capsule(np.add(hp, (0, -0.03, 0)), np.add(kn, (0, 0.02, 0)), 0.06), r.j(f"{side}UpLeg"), None),
                  (capsule(np.add(kn, (0, -0.02, 0)), np.add(an, (0, 0.02, 0)), 0.05), r.j(f"{side}Leg"), None),
                  (capsule(np.add(an, (0, -0.03, 0)), np.add(an, (0, -0.03, 0.12)), 0.04), r.j(f"{side}Foot"), None)]
    r.part(parts)
    r.still(frames)
    ph = _phase(frames)
    r.rotations[:, r.j("LeftArm")] = quat([0, 0, 1], 0.3 + 0.6 * (1 - np.cos(ph)))
    r.rotations[:, r.j("LeftForeArm")] = quat([0, 1, 0], 0.8 * np.sin(ph) ** 2)
    r.rotations[:, r.j("RightArm")] = quat([0, 0, 1], -1.1 * np.ones(frames))
    r.rotations[:, r.j("LeftUpLeg")] = quat([1, 0, 0], -0.5 * np.sin(ph) ** 2)
    r.rotations[:, r.j("LeftLeg")] = quat([1, 0, 0], 0.8 * np.sin(ph) ** 2)
    r.rotations[:, r.j("Spine")] = quat([0, 1, 0], 0.2 * np.sin(ph))
    r.rotations[:, r.j("Head")] = quat([1, 0, 0], 0.2 * np.sin(2 * ph))
    return r


def legged_creature(legs: int = 8, frames: int = 40, named: bool = True) -> Rig:
    """A body (thorax + abdomen) on `legs` three-bone legs (hip, knee, ankle, tip on the floor) spread
    around it, walking forward (+Z) with alternating leg groups; `named=False` numbers the joints only."""
    assert legs % 2 == 0
    r = Rig()
    r.add("body" if named else "joint0", None, (0, 0.3, 0))
    r.add("abdomen" if named else "joint1", r.names[0], (0, 0.32, -0.15))
    parts = [(sphere((0, 0.3, 0.02), 0.12, (1.0, 0.6, 1.3)), 0, None),
             (sphere((0, 0.34, -0.3), 0.16, (1.0, 0.8, 1.2)), 1, None)]
    per = legs // 2
    groups = []
    for k in range(per):
        z = 0.12 - 0.24 * k / max(per - 1, 1)
        for s, x in (("L", 1.0), ("R", -1.0)):
            out = np.array([x, 0.0, 1.5 * z])
            out /= np.linalg.norm(out)
            hip = np.array([0.07 * x, 0.3, z])
            knee = hip + 0.22 * out + [0, 0.16, 0]
            ankle = hip + 0.42 * out + [0, 0.02, 0]
            tip = np.array([ankle[0] + 0.1 * out[0], 0.0, ankle[2] + 0.1 * out[2]])
            base = f"leg{k + 1}{s}"
            names = []
            for part, p in (("hip", hip), ("knee", knee), ("ankle", ankle), ("tip", tip)):
                name = f"{base}_{part}" if named else f"joint{len(r.names)}"
                r.add(name, names[-1] if names else r.names[0], p)
                names.append(name)
            ji = [r.j(n) for n in names]
            parts += [blended(capsule(hip, knee, 0.025), hip, knee, 0, ji[0], 0.2),
                      blended(capsule(knee, ankle, 0.022), knee, ankle, ji[0], ji[1], 0.2),
                      blended(capsule(ankle, tip, 0.018), ankle, tip, ji[1], ji[2], 0.2)]
            groups.append(((k + (s == "R")) % 2, ji, out))
    r.part(parts)
    r.still(frames)
    ph = _phase(frames, 2.0)
    for g, ji, out in groups:
        p = ph + np.pi * g
        lift = np.clip(np.sin(p), 0.0, None)
        yaw = 0.3 * np.cos(p)
        side = np.cross([0, 1, 0], out)       # the axis that lifts the leg (about the leg's horizontal normal)
        r.rotations[:, ji[0]] = qmul(quat([0, 1, 0], yaw * np.sign(out[0])), quat(side, -0.35 * lift))
        r.rotations[:, ji[1]] = quat(side, 0.25 * lift)
    r.translation[:, 2] = 0.25 * np.arange(frames) / FPS
    r.translation[:, 1] = 0.3 + 0.01 * np.cos(2 * ph)
    return r


def write_glb(rig: Rig, path, animation: str = "Walk") -> None:
    """The rig as a GLB: joints with rest translations (no rest rotation), inverse bind matrices from the
    rest positions, one skinned mesh per part, and the animation sampled at `FPS` (linear)."""
    names, parents = rig.names, rig.parents
    pos = np.array(rig.rest)
    n = len(names)
    blob = bytearray()
    doc = gl.GLTF2(asset=gl.Asset(version="2.0"), scene=0, buffers=[], bufferViews=[], accessors=[])

    def accessor(array, kind, component, minmax=False):
        blob.extend(b"\0" * (-len(blob) % 4))
        data = np.ascontiguousarray(array)
        doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=data.nbytes))
        blob.extend(data.tobytes())
        acc = gl.Accessor(bufferView=len(doc.bufferViews) - 1, componentType=component, count=len(array), type=kind)
        if minmax:
            acc.min = np.atleast_1d(data.min(axis=0)).tolist()
            acc.max = np.atleast_1d(data.max(axis=0)).tolist()
        doc.accessors.append(acc)
        return len(doc.accessors) - 1

    ibm = np.stack([np.linalg.inv(np.block([[np.eye(3), pos[j][:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
                    for j in range(n)])
    doc.skins = [gl.Skin(joints=list(range(n)), inverseBindMatrices=accessor(
        ibm.transpose(0, 2, 1).reshape(n, 16).astype(np.float32), gl.MAT4, gl.FLOAT))]
    doc.nodes = []
    for j in range(n):
        offset = pos[j] - (pos[parents[j]] if parents[j] >= 0 else 0.0)
        children = [c for c in range(n) if parents[c] == j]
        doc.nodes.append(gl.Node(name=names[j], translation=offset.tolist(), children=children or None))
    doc.meshes = []
    for k, (verts, faces, joints, weights) in enumerate(rig.parts):
        w = weights / weights.sum(axis=1, keepdims=True)
        attrs = gl.Attributes(POSITION=accessor(verts.astype(np.float32), gl.VEC3, gl.FLOAT, True),
                              JOINTS_0=accessor(joints.astype(np.uint16), gl.VEC4, gl.UNSIGNED_SHORT),
                              WEIGHTS_0=accessor(w.astype(np.float32), gl.VEC4, gl.FLOAT))
        prim = gl.Primitive(attributes=attrs, indices=accessor(faces.reshape(-1).astype(np.uint32), gl.SCALAR,
                                                              gl.UNSIGNED_INT))
        doc.meshes.append(gl.Mesh(name=f"part{k}", primitives=[prim]))
        doc.nodes.append(gl.Node(name=f"part{k}", mesh=k, skin=0))
    roots = [j for j in range(n) if parents[j] < 0]
    doc.scenes = [gl.Scene(nodes=roots + list(range(n, n + len(rig.parts))))]
    if rig.rotations is not None:
        frames = len(rig.rotations)
        times = accessor((np.arange(frames) / FPS).astype(np.float32), gl.SCALAR, gl.FLOAT, True)
        samplers, channels = [], []
        for j in range(n):
            samplers.append(gl.AnimationSampler(input=times, output=accessor(
                rig.rotations[:, j].astype(np.float32), gl.VEC4, gl.FLOAT), interpolation="LINEAR"))
            channels.append(gl.AnimationChannel(sampler=len(samplers) - 1,
                                                target=gl.AnimationChannelTarget(node=j, path="rotation")))
        root = roots[0]
        samplers.append(gl.AnimationSampler(input=times, output=accessor(
            rig.translation.astype(np.float32), gl.VEC3, gl.FLOAT), interpolation="LINEAR"))
        channels.append(gl.AnimationChannel(sampler=len(samplers) - 1,
                                            target=gl.AnimationChannelTarget(node=root, path="translation")))
        doc.animations = [gl.Animation(name=animation, samplers=samplers, channels=channels)]
    doc.buffers = [gl.Buffer(byteLength=len(blob))]
    doc.set_binary_blob(bytes(blob))
    doc.save_binary(str(path))
