"""The independent glTF player on files written here by hand with pygltflib, whose poses are known in closed
form: a two-bone skin under a moved and scaled parent, a rigid mesh under an animated node, a morph target,
the three interpolations, animations picked by name."""
from __future__ import annotations

import numpy as np
import pygltflib as gl
import pytest

from export.gltf_player import GltfFile, sample

FLOAT, UINT16, UINT32 = 5126, 5123, 5125


class Builder:
    """A glTF document and its binary buffer, filled accessor by accessor."""

    def __init__(self):
        self.doc = gl.GLTF2(asset=gl.Asset(version="2.0"), scene=0, scenes=[gl.Scene(nodes=[])], nodes=[],
                            meshes=[], skins=[], animations=[], accessors=[], bufferViews=[], buffers=[])
        self.blob = bytearray()

    def accessor(self, array, kind: str, component: int = FLOAT) -> int:
        data = np.ascontiguousarray(array, dtype={FLOAT: "<f4", UINT16: "<u2", UINT32: "<u4"}[component])
        while len(self.blob) % 4:
            self.blob.append(0)
        self.doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=data.nbytes))
        self.blob += data.tobytes()
        flat = data.reshape(len(data), -1)
        extra = {"min": flat.min(0).tolist(), "max": flat.max(0).tolist()} if component == FLOAT else {}
        self.doc.accessors.append(gl.Accessor(bufferView=len(self.doc.bufferViews) - 1, componentType=component,
                                              count=len(data), type=kind, **extra))
        return len(self.doc.accessors) - 1

    def node(self, parent: int | None = None, **fields) -> int:
        self.doc.nodes.append(gl.Node(**fields))
        i = len(self.doc.nodes) - 1
        if parent is None:
            self.doc.scenes[0].nodes.append(i)
        else:
            parent_node = self.doc.nodes[parent]
            parent_node.children = (parent_node.children or []) + [i]
        return i

    def mesh(self, positions, triangles, targets=None, **attributes) -> int:
        attrs = gl.Attributes(POSITION=self.accessor(positions, "VEC3"), **attributes)
        prim = gl.Primitive(attributes=attrs, indices=self.accessor(np.ravel(triangles), "SCALAR", UINT32))
        if targets is not None:
            prim.targets = [{"POSITION": self.accessor(t, "VEC3")} for t in targets]
        self.doc.meshes.append(gl.Mesh(primitives=[prim]))
        return len(self.doc.meshes) - 1

    def animation(self, name: str, channels) -> None:
        """channels: (node, path, interpolation, times, values) each."""
        samplers, chans = [], []
        for node, path, interp, times, values in channels:
            kind = "SCALAR" if path == "weights" else {3: "VEC3", 4: "VEC4"}[np.shape(values)[1]]
            values = np.ravel(values) if path == "weights" else values
            samplers.append(gl.AnimationSampler(input=self.accessor(np.reshape(times, (-1, 1)), "SCALAR"),
                                                output=self.accessor(values, kind), interpolation=interp))
            chans.append(gl.AnimationChannel(sampler=len(samplers) - 1,
                                             target=gl.AnimationChannelTarget(node=node, path=path)))
        self.doc.animations.append(gl.Animation(name=name, samplers=samplers, channels=chans))

    def save(self, path) -> GltfFile:
        self.doc.buffers.append(gl.Buffer(byteLength=len(self.blob)))
        self.doc.set_binary_blob(bytes(self.blob))
        self.doc.save_binary(str(path))
        return GltfFile(path)


def quat_z(degrees: float) -> list[float]:
    h = np.radians(degrees) / 2
    return [0.0, 0.0, float(np.sin(h)), float(np.cos(h))]


def translate_scale(t, s) -> np.ndarray:
    m = np.diag([s, s, s, 1.0])
    m[:3, 3] = t
    return m


@pytest.fixture(scope="module")
def two_bones(tmp_path_factory):
    """A column of vertices up +Y from 0 to 2, the lower half on a root bone, the upper half on a child bone at
    y = 1, the skeleton under a parent moved by (5, 0, 0) and scaled by 2. "bend" turns the child 90 deg about
    +Z over a second; "lift" moves the root up by 1 (STEP, at t = 0.5)."""
    b = Builder()
    ys = np.linspace(0.0, 2.0, 9)
    local = np.stack([np.zeros(9), ys, np.zeros(9)], axis=1)
    parent = translate_scale([5.0, 0.0, 0.0], 2.0)
    world = local @ parent[:3, :3].T + parent[:3, 3]   # the bind shape, in world space
    joints = np.zeros((9, 4), int)
    joints[:, 0] = (ys > 1.0).astype(int)
    joints[ys == 1.0, :2] = [0, 1]
    weights = np.zeros((9, 4))
    weights[:, 0] = 1.0
    weights[ys == 1.0, :2] = 0.5
    tri = [[i, i + 1, (i + 2) % 9] for i in range(7)]
    mesh = b.mesh(world + [[0.1 * (i % 2), 0, 0] for i in range(9)], tri,
                  JOINTS_0=b.accessor(joints, "VEC4", UINT16), WEIGHTS_0=b.accessor(weights, "VEC4"))
    top = b.node(name="parent", translation=[5.0, 0.0, 0.0], scale=[2.0, 2.0, 2.0])
    root = b.node(top, name="root")
    child = b.node(root, name="child", translation=[0.0, 1.0, 0.0])
    # the skinned mesh node's own transform is ignored by a player
    b.node(name="body", mesh=mesh, skin=0, translation=[100.0, 0.0, 0.0])
    bind = [parent, parent @ translate_scale([0.0, 1.0, 0.0], 1.0)]
    ibm = np.stack([np.linalg.inv(m).T for m in bind])             # column-major
    b.doc.skins.append(gl.Skin(joints=[root, child], inverseBindMatrices=b.accessor(ibm.reshape(2, 16), "MAT4")))
    b.animation("bend", [(child, "rotation", "LINEAR", [0.0, 1.0], [quat_z(0), quat_z(90)])])
    b.animation("lift", [(root, "translation", "STEP", [0.0, 0.5], [[0, 0, 0], [0, 1, 0]])])
    return b.save(tmp_path_factory.mktemp("player") / "two_bones.glb"), world + [[0.1 * (i % 2), 0, 0]
                                                                                 for i in range(9)]


def test_the_bind_pose_is_the_bind_shape(two_bones):
    player, bind = two_bones
    assert np.allclose(player.vertices(0.0, None), bind, atol=1e-6)
    assert np.allclose(player.vertices(0.0, "bend"), bind, atol=1e-6)


def test_a_bent_child_bone_turns_its_vertices_about_its_world_joint(two_bones):
    player, bind = two_bones
    hinge = np.array([5.0, 2.0, 0.0])        # the child joint, y = 1 under the parent's scale 2
    for t, deg in ((1.0, 90.0), (0.5, 45.0), (2.0, 90.0)):
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        got = player.vertices(t, "bend")
        upper = bind[:, 1] > 2.0 + 1e-9
        assert np.allclose(got[upper], (bind[upper] - hinge) @ turn.T + hinge, atol=1e-5)
        assert np.allclose(got[bind[:, 1] < 2.0 - 1e-9], bind[bind[:, 1] < 2.0 - 1e-9], atol=1e-6)
        middle = np.abs(bind[:, 1] - 2.0) < 1e-9      # half on each bone: the mean of both
        assert np.allclose(got[middle], 0.5 * (bind[middle] + (bind[middle] - hinge) @ turn.T + hinge), atol=1e-5)


def test_animations_are_picked_by_name_or_index_and_step_holds(two_bones):
    player, bind = two_bones
    assert player.animation_index("lift") == 1 and player.animation_index(1) == 1
    assert np.allclose(player.vertices(0.49, "lift"), bind, atol=1e-6)
    # the root moves by 1 in the parent's frame: 2 in the world
    assert np.allclose(player.vertices(0.5, 1), bind + [0.0, 2.0, 0.0], atol=1e-6)
    assert player.time_range("bend") == (0.0, 1.0)
    with pytest.raises(KeyError):
        player.animation_index("dance")


@pytest.fixture(scope="module")
def rigid_and_morph(tmp_path_factory):
    """An unskinned triangle under an animated node, turned 90 deg about +Z at rest; a second triangle with
    one morph target (+1 in y) whose weight goes 0 -> 1 over a second."""
    b = Builder()
    tri = np.array([[1.0, 0, 0], [2.0, 0, 0], [1.0, 1.0, 0]])
    rigid = b.mesh(tri, [[0, 1, 2]])
    morph = b.mesh(tri, [[0, 1, 2]], targets=[np.tile([0.0, 1.0, 0.0], (3, 1))])
    mover = b.node(name="mover")
    b.node(mover, name="rigid", mesh=rigid, rotation=quat_z(90))
    shape = b.node(name="shape", mesh=morph, translation=[0.0, 0.0, 3.0])
    b.animation("go", [(mover, "translation", "LINEAR", [0.0, 1.0], [[0, 0, 0], [4, 0, 0]]),
                       (shape, "weights", "LINEAR", [0.0, 1.0], [[0.0], [1.0]])])
    return b.save(tmp_path_factory.mktemp("player") / "rigid.glb"), tri


def test_a_rigid_mesh_follows_its_animated_parent_and_a_morph_target_blends(rigid_and_morph):
    player, tri = rigid_and_morph
    assert player.vertex_count == 6 and len(player.pieces) == 2
    assert np.array_equal(player.triangles(), [[0, 1, 2], [3, 4, 5]])
    turned = tri @ np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]]).T
    got = player.vertices(0.25, "go")
    assert np.allclose(got[:3], turned + [1.0, 0.0, 0.0], atol=1e-6)
    assert np.allclose(got[3:], tri + [0.0, 0.25, 3.0], atol=1e-6)
    assert np.allclose(player.vertices(0.0, None)[3:], tri + [0.0, 0.0, 3.0], atol=1e-6)


def test_the_three_interpolations():
    times = np.array([0.0, 2.0])
    assert sample(times, np.array([[0.0], [1.0]]), "STEP", 1.9)[0] == 0.0
    assert sample(times, np.array([[0.0], [1.0]]), "LINEAR", 0.5)[0] == pytest.approx(0.25)
    # Hermite: value 0 -> 1 over dt = 2, out-tangent 1 at the first key, in-tangent 0 at the second; at u = 1/2:
    # h00·0 + h10·dt·1 + h01·1 + h11·dt·0 = 0.125·2 + 0.5
    cubic = np.array([[9.0], [0.0], [1.0], [0.0], [1.0], [9.0]])     # (in, value, out) per key
    assert sample(times, cubic, "CUBICSPLINE", 1.0)[0] == pytest.approx(0.75)
    assert sample(times, cubic, "CUBICSPLINE", 5.0)[0] == 1.0          # clamped after the last key
    # quaternions: slerp on the shortest arc, the far sign of the second key included
    q = sample(times, np.array([quat_z(0), -np.array(quat_z(90))]), "LINEAR", 1.0, rotation=True)
    assert np.allclose(np.abs(q), np.abs(quat_z(45)), atol=1e-9)


@pytest.mark.slow
def test_weights_not_summing_to_one_are_posed_as_three_js_poses_them(data_dir):
    """CesiumMan's WEIGHTS_0 sum to as little as 0.18 on some vertices (the validator's
    ACCESSOR_WEIGHTS_NON_NORMALIZED): three.js's GLTFLoader divides them by their sum, and so does the player, so
    those vertices stay on the body instead of being pulled toward the skeleton's origin."""
    import json
    import subprocess
    from pathlib import Path

    path = data_dir / "avatars" / "CesiumMan.glb"
    player = GltfFile(path)
    raw = [player.accessor(player.doc.meshes[p.mesh].primitives[p.primitive].attributes.WEIGHTS_0)
           for p in player.pieces]
    assert min(float(w.sum(axis=1).min()) for w in raw) < 0.5      # the file's own weights are not normalised
    three = Path(__file__).resolve().parents[1] / "avatar" / "node" / "skin_three.mjs"
    times = (0.0, 0.6, 1.3)
    out = json.loads(subprocess.run(["node", str(three), str(path), *map(str, times)], capture_output=True,
                                    text=True, timeout=300, check=True).stdout)
    diag = float(np.linalg.norm(np.ptp(player.vertices(0.0, 0), axis=0)))
    for t, frame in zip(times, out["frames"]):
        page = np.concatenate([np.array(m["positions"]).reshape(-1, 3) for m in frame])
        assert np.linalg.norm(player.vertices(t, 0) - page, axis=1).max() <= 1e-4 * diag, t
