"""Loading rigged glTF: the bind pose comes from the inverse bind matrices (whatever the nodes' rest pose),
skinning the bind pose gives the authored mesh, and bad files get one clear error."""
from __future__ import annotations

import numpy as np
import pygltflib
import pytest
import trimesh

from kinetre.avatar.load import load_avatar
from kinetre.avatar.skin import skin_avatar
from kinetre.errors import BadAvatarError

from avatar.conftest import HUMANOIDS


@pytest.mark.parametrize("name", HUMANOIDS)
def test_the_bind_pose_skins_to_the_authored_mesh(rigged, name):
    avatar, _, _ = rigged[name]
    posed = skin_avatar(avatar, avatar.bind_world[None])[0]
    for prim, v in zip(avatar.primitives, posed):
        # the glTF spec places a skinned mesh by its joints; at bind that is the mesh node's world matrix
        m = avatar.rest_world[prim.node]
        np.testing.assert_allclose(v, prim.positions @ m[:3, :3].T + m[:3, 3], atol=1e-5 * np.ptp(v))


def test_a_file_saved_mid_animation_still_binds_by_its_inverse_bind_matrices(data_dir, tmp_path, rigged):
    reference, _, _ = rigged["CesiumMan"]
    doc = pygltflib.GLTF2.load(str(data_dir / "avatars" / "CesiumMan.glb"))
    rng = np.random.default_rng(0)
    for node in doc.skins[0].joints[3:12]:                  # bend a dozen joints away from the bind pose
        q = rng.normal(size=4)
        doc.nodes[node].rotation = (q / np.linalg.norm(q)).tolist()
    path = tmp_path / "posed.glb"
    doc.save_binary(str(path))
    avatar = load_avatar(path)
    np.testing.assert_allclose(avatar.bind_world, reference.bind_world, atol=1e-6)
    np.testing.assert_allclose(skin_avatar(avatar, avatar.bind_world[None])[0][0],
                               skin_avatar(reference, reference.bind_world[None])[0][0], atol=1e-6)


def test_bad_files_get_one_clear_error(tmp_path, data_dir):
    with pytest.raises(BadAvatarError, match="nothere.glb: no such file"):
        load_avatar(tmp_path / "nothere.glb")
    with pytest.raises(BadAvatarError, match="chair.obj: an avatar must be a rigged .glb, .gltf or .vrm"):
        load_avatar(tmp_path / "chair.obj")
    broken = tmp_path / "broken.glb"
    broken.write_bytes((data_dir / "avatars" / "CesiumMan.glb").read_bytes()[:5000])
    with pytest.raises(BadAvatarError, match="broken.glb: "):
        load_avatar(broken)
    plain = tmp_path / "box.glb"
    plain.write_bytes(trimesh.creation.box().export(file_type="glb"))
    with pytest.raises(BadAvatarError, match=r"box.glb: no skinned mesh .*kinetre animate box.glb"):
        load_avatar(plain)
