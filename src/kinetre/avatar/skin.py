"""The avatar's own linear blend skinning, as a glTF player does it (the avateering paper's skinning step, KinÊtre Eq. 1):

    v' = Σ_k w_k · (World_k · IBM_k) · v,

with World_k the joint's posed world matrix, IBM_k its inverse bind matrix and the weights normalised to
sum 1. The paper blends two bones per vertex; glTF gives four, used as they are.
"""
from __future__ import annotations

import numpy as np

from ..mesh.mesh import Mesh
from .load import Avatar


def joint_matrices(avatar: Avatar, world: np.ndarray) -> np.ndarray:
    """(T, J, 4, 4) skinning matrices World_k · IBM_k for posed joint world matrices `world` (T, J, 4, 4)."""
    return np.einsum("tjab,jbc->tjac", world, avatar.inverse_bind)


def skin_avatar(avatar: Avatar, world: np.ndarray, normals: bool = False):
    """Skinned vertices of every primitive, for each frame.

    Parameters
    ----------
    avatar : Avatar
    world : (T, J, 4, 4) float64
        Joint world matrices per frame (`avatar.bind_world[None]` gives the bind pose).
    normals : bool
        Also return the skinned normals (by the blended linear part, renormalised).

    Returns
    -------
    list over frames of lists over primitives of (V, 3) float64 positions; with `normals`, a pair
    (positions, normals) of such lists.

    >>> from kinetre.avatar.load import load_avatar                          # doctest: +SKIP
    >>> a = load_avatar("CesiumMan.glb"); v = skin_avatar(a, a.bind_world[None])[0]   # doctest: +SKIP
    """
    mats = joint_matrices(avatar, np.asarray(world, dtype=np.float64))
    out_p, out_n = [], []
    for m in mats:
        frame_p, frame_n = [], []
        for prim in avatar.primitives:
            blend = np.einsum("vk,vkab->vab", prim.weights, m[prim.joints])          # (V, 4, 4)
            frame_p.append(np.einsum("vab,vb->va", blend[:, :3, :3], prim.positions) + blend[:, :3, 3])
            if normals:
                n = np.einsum("vab,vb->va", blend[:, :3, :3], prim.normals)
                frame_n.append(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300))
        out_p.append(frame_p)
        out_n.append(frame_n)
    return (out_p, out_n) if normals else out_p


def posed_mesh(avatar: Avatar, world: np.ndarray) -> Mesh:
    """The skin posed by the joint world matrices `world` (J, 4, 4) as one plain mesh (every primitive's
    triangles, no normals): what a tool that flattens the rig would write."""
    parts = skin_avatar(avatar, np.asarray(world)[None])[0]
    offsets = np.cumsum([0] + [len(p) for p in parts])
    vertices = np.vstack(parts)
    faces = np.vstack([prim.faces + o for prim, o in zip(avatar.primitives, offsets)])
    return Mesh(vertices=vertices, faces=faces, normals=np.zeros_like(vertices), source=avatar.source)


def bind_bounds(avatar: Avatar) -> tuple[np.ndarray, np.ndarray]:
    """(3,) min and max corners of the skinned mesh in the bind pose (world)."""
    v = np.concatenate(skin_avatar(avatar, avatar.bind_world[None])[0])
    return v.min(axis=0), v.max(axis=0)
