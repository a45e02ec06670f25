"""Skeleton attachment (KinÊtre paper, "Constraints"): joints and bone-cylinder samples become point constraints.

A joint within `reach` (10 cm) of the graph is carried by its 4 nearest nodes (Euclidean, linear
falloff). Each bone is a cylinder of radius 4 cm with 16 samples (4 rings × 4 around) and outward
normals; a sample attaches to the nodes within `reach` whose normals are < 90° from its own, so the
front of an arm attaches to the front of the mesh's arm.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree

from ..deform.constraints import PointConstraints
from ..graph.graph import DeformationGraph
from ..mesh.mesh import Mesh
from ..jit import njit
from ..rotation import minimal_rotation_into
from .carrying import carrying_bones
from .models import Skeleton
from .piece_bones import piece_bones

RINGS = 4
AROUND = 4


@dataclass(frozen=True, eq=False)
class SkeletonAttachment:
    """The constraints one skeleton contributes, and how to move their targets per frame.

    Attributes
    ----------
    constraints : PointConstraints
    joint : (L,) int32
        For joint constraints the joint index, else -1.
    bone : (L,) int32
        For bone samples the bone's row in model.bones, else -1.
    offset : (L, 3) float64
        Bone samples: bind position minus the bone's parent joint at bind time.
    bind : Skeleton
        The pose at possession.
    twist_reference : (B,) int32
        Per bone of the model, a neighbouring bone whose direction fixes the twist about this
        bone (-1: none, the minimal rotation is used).
    """

    constraints: PointConstraints
    joint: np.ndarray
    bone: np.ndarray
    offset: np.ndarray
    bind: Skeleton
    twist_reference: np.ndarray

    @property
    def joint_count(self) -> int:
        return int((self.joint >= 0).sum())

    @property
    def bone_sample_count(self) -> int:
        return int((self.bone >= 0).sum())


def _frame(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors perpendicular to `direction` and to each other."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(direction, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(direction, u)


def bone_samples(a: np.ndarray, b: np.ndarray, radius: float = 0.04) -> tuple[np.ndarray, np.ndarray]:
    """16 points on the cylinder around segment a→b and their outward normals: (16, 3), (16, 3)."""
    axis = b - a
    length = np.linalg.norm(axis)
    d = axis / length
    u, v = _frame(d)
    pts, nrm = [], []
    for ring in range(RINGS):
        s = (ring + 0.5) / RINGS
        for k in range(AROUND):
            # alternate rings are turned by half a step so samples cover the circumference evenly
            ang = 2 * np.pi * (k + 0.5 * (ring % 2)) / AROUND
            n = np.cos(ang) * u + np.sin(ang) * v
            pts.append(a + s * axis + radius * n)
            nrm.append(n)
    return np.array(pts), np.array(nrm)


def _carry(nodes: np.ndarray, candidates: np.ndarray, point: np.ndarray, neighbours=None, k: int = 4):
    """Up to k nearest candidate nodes with linear-falloff weights (Eq. 2), padded to 4.

    With `neighbours` (per node, its graph neighbours) the carriers are kept to the nearest candidate
    and its graph neighbours (ours): carriers that are already coupled by E_reg add no new coupling
    to JᵀJ, which keeps the Cholesky factor ~2× sparser at the same tracking accuracy.
    """
    d = np.linalg.norm(nodes[candidates] - point, axis=1)
    if neighbours is not None and len(candidates) > 1:
        first = candidates[np.argmin(d)]
        local = np.isin(candidates, neighbours[first]) | (candidates == first)
        candidates, d = candidates[local], d[local]
    order = np.argsort(d)
    take = order[:k]
    dmax = d[order[k]] if len(order) > k else d[take].max() * 1.5 + 1e-12
    w = np.maximum(1.0 - d[take] / dmax, 0.0)
    w = w / w.sum() if w.sum() > 0 else np.full(len(take), 1.0 / len(take))
    idx = np.full(4, candidates[take[0]], dtype=np.int32)
    ww = np.zeros(4)
    idx[:len(take)] = candidates[take]
    ww[:len(take)] = w
    return idx, ww


def attach_skeleton(graph: DeformationGraph, skeleton: Skeleton, joint_mask: np.ndarray,
                    reach: float = 0.10, bone_radius: float = 0.04, node_bones: bool = False,
                    mesh: Mesh | None = None) -> SkeletonAttachment:
    """Point constraints for one skeleton at its bind pose (the pose at "possess").

    With `node_bones` every graph node also follows its bone (ours, for a skeleton that stands where the
    mesh's artist put it): a constraint at the node itself, moved as a bone sample, so parts beyond the bone
    cylinders' reach (a big head, a broad torso) are carried by their bone too. The bone is the one the node
    sees from inside the mesh when `mesh` is given (`carrying_bones`), else the nearest; a bone's cylinder
    samples are then carried by its own nodes only, so a leg's samples next to the hip do not drag the belly.

    Parameters
    ----------
    graph : DeformationGraph (in the skeleton's units: metres)
    skeleton : Skeleton, the bind pose
    joint_mask : (J,) bool, the subset that may attach; a bone needs both of its joints
    reach : float, attachment distance (10 cm)
    bone_radius : float, bone cylinder radius (4 cm)
    node_bones : bool, carry every node by its bone as well
    mesh : Mesh or None, the graph's mesh in the same frame: with `node_bones` a multi-part mesh's pieces
        are told which bones run through them from their own triangles (`piece_bones`), and each node's bone
        is the one it sees through the mesh's inside (`carrying_bones`)
    """
    nodes, normals = graph.nodes, graph.normals
    tree = cKDTree(nodes)
    neighbours = graph.neighbours()
    pos, tracked = skeleton.positions, skeleton.tracked
    points, idx, wts, joint_of, bone_of, offsets = [], [], [], [], [], []
    use = joint_mask & tracked
    # a skeleton standing inside a multi-part mesh carries each piece by the bones that run through it only
    allowed = piece_bones(graph, skeleton, joint_mask, mesh) if node_bones else None
    # a skeleton standing where the artist put it carries the mesh by the bones the artist's skin follows
    carries = skeleton.model.skinning_bones if node_bones else np.ones(len(skeleton.model.bones), bool)
    if node_bones:
        # a joint outside the graph's box (a rig's helper, an IK pole target) carries none of the mesh
        lo, hi = nodes.min(axis=0) - reach, nodes.max(axis=0) + reach
        within = use & ((pos >= lo) & (pos <= hi)).all(axis=1)
        mask = np.broadcast_to(carries, (len(nodes), len(carries))) if allowed is None else allowed[graph.pieces]
        carriers = nearest_bones(nodes, skeleton, within, mask) if mesh is None else \
            carrying_bones(graph, skeleton, within, mesh, mask)
    for j in np.flatnonzero(use):
        near = tree.query_ball_point(pos[j], reach)
        if not near:
            continue
        # the 4 nearest nodes overall (some may be a little beyond reach), as the paper's joints
        _, nearest = tree.query(pos[j], k=min(8, len(nodes)))
        i, w = _carry(nodes, np.atleast_1d(nearest), pos[j], neighbours)
        points.append(pos[j]), idx.append(i), wts.append(w)
        joint_of.append(j), bone_of.append(-1), offsets.append(np.zeros(3))
    for bi, (p, c) in enumerate(skeleton.model.bones):
        if not (use[p] and use[c] and carries[bi]) or np.linalg.norm(pos[c] - pos[p]) < 1e-6:
            continue
        sp, sn = bone_samples(pos[p], pos[c], bone_radius)
        for q, n in zip(sp, sn):
            near = np.array(tree.query_ball_point(q, reach), dtype=np.int64)
            if near.size == 0:
                continue
            near = near[normals[near] @ n > 0.0]
            if allowed is not None:
                near = near[allowed[graph.pieces[near], bi]]
            if node_bones:  # a bone's samples pull only on the nodes it carries, not on a neighbour's beside it
                near = near[carriers[near] == bi]
            if near.size == 0:
                continue
            i, w = _carry(nodes, near, q, neighbours)
            points.append(q), idx.append(i), wts.append(w)
            joint_of.append(-1), bone_of.append(bi), offsets.append(q - pos[p])
    if node_bones:
        for j, bi in enumerate(carriers):
            if bi < 0:
                continue
            points.append(nodes[j]), idx.append(np.full(4, j, np.int32)), wts.append(np.array([1.0, 0, 0, 0]))
            joint_of.append(-1), bone_of.append(bi), offsets.append(nodes[j] - pos[skeleton.model.bones[bi][0]])
    if points:
        cons = PointConstraints(np.array(points), np.array(idx, dtype=np.int32), np.array(wts))
    else:
        cons = PointConstraints.empty()
    return SkeletonAttachment(cons, np.array(joint_of, dtype=np.int32), np.array(bone_of, dtype=np.int32),
                              np.array(offsets).reshape(-1, 3), skeleton, twist_references(skeleton))


def nearest_bones(points: np.ndarray, skeleton: Skeleton, joint_mask: np.ndarray,
                  allowed: np.ndarray | None = None) -> np.ndarray:
    """(P,) int: per point the row in model.bones of the nearest bone (as a segment) whose joints are both in
    `joint_mask` (and, with `allowed` (P, B) bool, that the point may take), or -1 when there is none."""
    bones = np.asarray(skeleton.model.bones, dtype=np.int64).reshape(-1, 2)
    pos = skeleton.positions
    ok = joint_mask[bones[:, 0]] & joint_mask[bones[:, 1]]
    ok &= np.linalg.norm(pos[bones[:, 1]] - pos[bones[:, 0]], axis=1) > 1e-9
    if not ok.any():
        return np.full(len(points), -1)
    rows = np.flatnonzero(ok)
    a, b = pos[bones[rows, 0]], pos[bones[rows, 1]]
    ab = b - a
    s = np.einsum("pbi,bi->pb", points[:, None] - a[None], ab) / np.einsum("bi,bi->b", ab, ab)
    closest = a[None] + np.clip(s, 0.0, 1.0)[..., None] * ab[None]
    dist = np.linalg.norm(points[:, None] - closest, axis=2)
    if allowed is not None:
        dist = np.where(allowed[:, rows], dist, np.inf)
    best = np.argmin(dist, axis=1)
    return np.where(np.isfinite(dist[np.arange(len(points)), best]), rows[best], -1)


def twist_references(skeleton: Skeleton, min_sine: float = 0.2) -> np.ndarray:
    """For each bone, the neighbouring bone (sharing a joint) most perpendicular to it at bind time.

    A bone's direction alone leaves its twist free; the plane it spans with a neighbour does not,
    so a rigid motion of the whole skeleton moves every bone sample rigidly. Bones with no
    neighbour at least asin(`min_sine`) off their axis get -1.
    """
    bones = skeleton.model.bones
    pos, tracked = skeleton.positions, skeleton.tracked
    ref = np.full(len(bones), -1, dtype=np.int32)
    d = pos[bones[:, 1]] - pos[bones[:, 0]]
    length = np.linalg.norm(d, axis=1)
    ok = tracked[bones[:, 0]] & tracked[bones[:, 1]] & (length > 1e-9)
    u = d / np.where(length > 1e-9, length, 1.0)[:, None]
    for b in np.flatnonzero(ok):
        shares = np.isin(bones[:, 0], bones[b]) | np.isin(bones[:, 1], bones[b])
        shares[b] = False
        cand = np.flatnonzero(shares & ok)
        if cand.size == 0:
            continue
        sine = np.linalg.norm(np.cross(u[cand], u[b]), axis=1)
        best = np.argmax(sine)
        if sine[best] >= min_sine:
            ref[b] = cand[best]
    return ref


def bone_rotations(bind: Skeleton, frame: Skeleton, reference: np.ndarray) -> np.ndarray:
    """(B, 3, 3) rotation of every bone of the model from the bind pose to `frame`.

    A bone with a twist reference turns as the frame spanned by it and that neighbour; a bone
    without one (a straight arm in a T-pose) carries its parent bone's rotation, corrected by the
    minimal rotation that aligns the result with its own direction; a bone with neither turns by the
    minimal rotation alone. Under a rigid motion of the whole skeleton every bone gets exactly that
    rotation.
    """
    bones, parent_bones = _bone_arrays(frame.model)
    return _bone_rotations(np.asarray(bind.positions, dtype=np.float64), np.asarray(frame.positions, dtype=np.float64),
                           np.asarray(frame.tracked, dtype=np.bool_), bones, np.asarray(reference, dtype=np.int64),
                           parent_bones)


@lru_cache(maxsize=16)
def _bone_arrays(model) -> tuple[np.ndarray, np.ndarray]:
    """The model's bones (B, 2) int64 and per bone the bone ending at its first joint (-1 at the root);
    once per model, not per frame."""
    bones = np.asarray(model.bones, dtype=np.int64)
    by_child = np.full(len(model.joints), -1, np.int64)
    by_child[bones[:, 1]] = np.arange(len(bones))
    bones.setflags(write=False)
    parents = by_child[bones[:, 0]]
    parents.setflags(write=False)
    return bones, parents


@njit(cache=True)
def _unit_into(v0, v1, v2, out):
    """out ← v / |v| and True, or 0 and False for a zero, tiny or non-finite v (an untracked joint may sit at
    inf)."""
    n = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if n > 1e-12 and np.isfinite(n):
        out[0], out[1], out[2] = v0 / n, v1 / n, v2 / n
        return True
    out[0] = out[1] = out[2] = 0.0
    return False


@njit(cache=True)
def _perpendicular_unit(r, u, out):
    """out ← the unit part of r perpendicular to the unit vector u (`_unit_into`)."""
    d = r[0] * u[0] + r[1] * u[1] + r[2] * u[2]
    return _unit_into(r[0] - d * u[0], r[1] - d * u[1], r[2] - d * u[2], out)


@njit(cache=True)
def _bone_rotations(bind, pos, tracked, bones, reference, parent_bone):
    # scalar arithmetic into preallocated rows: per frame this runs for every bone of every skeleton, where
    # small temporary arrays and BLAS calls on 3-vectors and 3×3 products cost more than the maths
    nb = bones.shape[0]
    rot = np.empty((nb, 3, 3))
    u0 = np.empty((nb, 3))
    u1 = np.empty((nb, 3))
    ok1 = np.empty(nb, np.bool_)
    own = np.zeros(nb, np.bool_)
    for b in range(nb):
        p, c = bones[b, 0], bones[b, 1]
        _unit_into(bind[c, 0] - bind[p, 0], bind[c, 1] - bind[p, 1], bind[c, 2] - bind[p, 2], u0[b])
        ok = _unit_into(pos[c, 0] - pos[p, 0], pos[c, 1] - pos[p, 1], pos[c, 2] - pos[p, 2], u1[b])
        ok1[b] = ok and tracked[p] and tracked[c]
        if not ok1[b]:
            u1[b] = u0[b]
        minimal_rotation_into(u0[b], u1[b], rot[b])
    r0 = np.empty(3)
    r1 = np.empty(3)
    w0 = np.empty(3)
    w1 = np.empty(3)
    for b in range(nb):
        r = reference[b]
        if r < 0 or not (tracked[bones[r, 0]] and tracked[bones[r, 1]] and ok1[b]):
            continue
        for i in range(3):
            r0[i] = bind[bones[r, 1], i] - bind[bones[r, 0], i]
            r1[i] = pos[bones[r, 1], i] - pos[bones[r, 0], i]
        if not (_perpendicular_unit(r0, u0[b], w0) and _perpendicular_unit(r1, u1[b], w1)):
            continue
        # the frames (u, w, u × w) at bind and now: rot = F1 F0ᵀ = u1 u0ᵀ + w1 w0ᵀ + (u1 × w1)(u0 × w0)ᵀ
        a, e = u0[b], u1[b]
        c0 = (a[1] * w0[2] - a[2] * w0[1], a[2] * w0[0] - a[0] * w0[2], a[0] * w0[1] - a[1] * w0[0])
        c1 = (e[1] * w1[2] - e[2] * w1[1], e[2] * w1[0] - e[0] * w1[2], e[0] * w1[1] - e[1] * w1[0])
        for i in range(3):
            for j in range(3):
                rot[b, i, j] = e[i] * a[j] + w1[i] * w0[j] + c1[i] * c0[j]
        own[b] = True
    # parents come before children in the model's joint order, so one pass sees every parent first
    turned = np.empty(3)
    m = np.empty((3, 3))
    for b in range(nb):
        pb = parent_bone[b]
        if own[b] or pb < 0 or not ok1[b]:
            continue
        for i in range(3):
            turned[i] = rot[pb, i, 0] * u0[b, 0] + rot[pb, i, 1] * u0[b, 1] + rot[pb, i, 2] * u0[b, 2]
        minimal_rotation_into(turned, u1[b], m)
        for i in range(3):
            for j in range(3):
                rot[b, i, j] = m[i, 0] * rot[pb, 0, j] + m[i, 1] * rot[pb, 1, j] + m[i, 2] * rot[pb, 2, j]
    return rot


def framed_rotations(bind: Skeleton, frame: Skeleton, rotations: np.ndarray) -> np.ndarray:
    """`rotations` (B, 3, 3), with every bone whose child joint has a source bone frame at bind and now
    (`Skeleton.bone_frames`) turned instead by the source's own rotation, twist included: F_now F_bindᵀ,
    aligned by the minimal rotation with the bone's tracked direction (a mapped bone may span several
    source bones)."""
    bones, _ = _bone_arrays(frame.model)
    out = np.array(rotations, dtype=np.float64)
    if bind.bone_frames is None or frame.bone_frames is None:
        return out
    _framed_rotations_into(np.asarray(bind.positions, np.float64), np.asarray(frame.positions, np.float64),
                           np.asarray(frame.tracked, np.bool_), bones, bind.bone_frames, frame.bone_frames, out)
    return out


@njit(cache=True)
def _framed_rotations_into(bind, pos, tracked, bones, bind_frames, frames, rot):
    u0 = np.empty(3)
    u1 = np.empty(3)
    turned = np.empty(3)
    m = np.empty((3, 3))
    r = np.empty((3, 3))
    for b in range(bones.shape[0]):
        p, c = bones[b, 0], bones[b, 1]
        if not (np.isfinite(bind_frames[c, 0, 0]) and np.isfinite(frames[c, 0, 0])):
            continue
        for i in range(3):
            for j in range(3):
                r[i, j] = frames[c, i, 0] * bind_frames[c, j, 0] + frames[c, i, 1] * bind_frames[c, j, 1] \
                    + frames[c, i, 2] * bind_frames[c, j, 2]
        if not np.isfinite(r).all():
            continue
        ok0 = _unit_into(bind[c, 0] - bind[p, 0], bind[c, 1] - bind[p, 1], bind[c, 2] - bind[p, 2], u0)
        ok1 = _unit_into(pos[c, 0] - pos[p, 0], pos[c, 1] - pos[p, 1], pos[c, 2] - pos[p, 2], u1)
        if ok0 and ok1 and tracked[p] and tracked[c]:
            for i in range(3):
                turned[i] = r[i, 0] * u0[0] + r[i, 1] * u0[1] + r[i, 2] * u0[2]
            minimal_rotation_into(turned, u1, m)
            for i in range(3):
                for j in range(3):
                    rot[b, i, j] = m[i, 0] * r[0, j] + m[i, 1] * r[1, j] + m[i, 2] * r[2, j]
        else:
            rot[b] = r


@dataclass(frozen=True, eq=False)
class StackedAttachments:
    """A rig's attachments stacked once at possession, so one numba call per frame moves the constraints of
    every skeleton (`stacked_targets`): per skeleton a block of rows in the joint arrays (`first_joint`), its
    bones and constraints after the previous skeleton's, with joint and bone indices shifted to match.

    Attributes
    ----------
    first_joint : (S + 1,) int64, skeleton s's joints are rows first_joint[s]:first_joint[s + 1]
    bind : (J, 3) the bind poses' joints; bones (B, 2), parent_bone (B,), twist_reference (B,) int64
    joint, bone : (L,) int64 per constraint its joint or bone row (-1: none); offset, points (L, 3)
    bind_frames : (J, 3, 3) the bind poses' source bone frames (NaN where a bind pose has none)
    """

    first_joint: np.ndarray
    bind: np.ndarray
    bones: np.ndarray
    parent_bone: np.ndarray
    twist_reference: np.ndarray
    joint: np.ndarray
    bone: np.ndarray
    offset: np.ndarray
    points: np.ndarray
    bind_frames: np.ndarray

    @property
    def framed(self) -> bool:
        """Whether any bind pose carries source bone frames (then frames' bone frames turn its bones)."""
        return bool(np.isfinite(self.bind_frames[:, 0, 0]).any())

    @staticmethod
    def of(attachments) -> "StackedAttachments":
        joints = bones = 0
        first, binds, bone_rows, parents, refs, joint, bone, offset, points = [0], [], [], [], [], [], [], [], []
        frames = []
        for att in attachments:
            model_bones, parent_bones = _bone_arrays(att.bind.model)
            binds.append(np.asarray(att.bind.positions, np.float64))
            frames.append(np.full((len(att.bind.model.joints), 3, 3), np.nan) if att.bind.bone_frames is None
                          else att.bind.bone_frames)
            bone_rows.append(model_bones + joints)
            parents.append(np.where(parent_bones >= 0, parent_bones + bones, -1))
            refs.append(np.where(att.twist_reference >= 0, att.twist_reference.astype(np.int64) + bones, -1))
            joint.append(np.where(att.joint >= 0, att.joint.astype(np.int64) + joints, -1))
            bone.append(np.where(att.bone >= 0, att.bone.astype(np.int64) + bones, -1))
            offset.append(att.offset.reshape(-1, 3)), points.append(att.constraints.points.reshape(-1, 3))
            joints += len(att.bind.model.joints)
            bones += len(model_bones)
            first.append(joints)

        def stack(parts, dtype, shape):
            return np.ascontiguousarray(np.concatenate(parts), dtype) if parts else np.zeros(shape, dtype)

        return StackedAttachments(np.array(first, np.int64), stack(binds, np.float64, (0, 3)),
                                  stack(bone_rows, np.int64, (0, 2)), stack(parents, np.int64, 0),
                                  stack(refs, np.int64, 0), stack(joint, np.int64, 0), stack(bone, np.int64, 0),
                                  stack(offset, np.float64, (0, 3)), stack(points, np.float64, (0, 3)),
                                  stack(frames, np.float64, (0, 3, 3)))


@njit(cache=True)
def stacked_targets(bind, bones, parent_bone, twist_reference, joint, bone, offset, points, pos, tracked, q, active,
                    bind_frames, frames):
    """`constraint_targets` of every skeleton at once on `StackedAttachments`' arrays and the frames' joints
    stacked the same way (pos (J, 3), tracked (J,), bone frames (J, 3, 3) or a (0, 3, 3) array for none):
    targets into q (L, 3), 1.0 / 0.0 per tracked / lost constraint into `active` (L,) (the solver's scales).
    Returns the number of tracked constraints."""
    rot = _bone_rotations(bind, pos, tracked, bones, twist_reference, parent_bone)
    if frames.shape[0] == bind_frames.shape[0] and frames.shape[0] > 0:
        _framed_rotations_into(bind, pos, tracked, bones, bind_frames, frames, rot)
    ok = _targets(joint, bone, offset, points, bind, pos, tracked, bones, rot, q)
    count = 0
    for i in range(ok.shape[0]):
        active[i] = 1.0 if ok[i] else 0.0
        count += ok[i]
    return count


def constraint_targets(att: SkeletonAttachment, frame: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """Targets q_ℓ (L, 3) for a new frame and the (L,) mask of constraints still tracked.

    Joints follow their joint. A bone sample turns with its bone: by the source's own bone rotation
    where the source carries joint rotations (`framed_rotations`: the twist is the source's), else by the
    minimal rotation from the bind direction to the current one, with the twist taken from a neighbouring
    bone where there is one. It moves with the parent joint, and slides along the bone with its length
    (ours: so samples near the child joint stay with it when tracked lengths vary).
    """
    pos = np.asarray(frame.positions, dtype=np.float64)
    tracked = np.asarray(frame.tracked, dtype=np.bool_)
    rot = np.zeros((0, 3, 3))
    if (att.bone >= 0).any():
        rot = framed_rotations(att.bind, frame, bone_rotations(att.bind, frame, att.twist_reference))
    q = np.zeros((len(att.joint), 3))
    ok = _targets(att.joint, att.bone, att.offset, att.constraints.points, np.asarray(att.bind.positions, np.float64),
                  pos, tracked, _bone_arrays(frame.model)[0], rot, q)
    return q, ok


@njit(cache=True)
def _targets(joint, bone, offset, points, bind, pos, tracked, bones, rot, q):
    """Targets into q (L, 3); returns the (L,) tracked mask."""
    # scalar arithmetic throughout: small temporary arrays per constraint cost more than the maths
    n = joint.shape[0]
    ok = np.zeros(n, np.bool_)
    for i in range(n):
        if joint[i] >= 0:
            for a in range(3):
                q[i, a] = pos[joint[i], a]
            ok[i] = tracked[joint[i]]
        elif bone[i] >= 0:
            p, c = bones[bone[i], 0], bones[bone[i], 1]
            l0 = 0.0
            l1 = 0.0
            axial = 0.0
            for a in range(3):
                d0 = bind[c, a] - bind[p, a]
                d1 = pos[c, a] - pos[p, a]
                l0 += d0 * d0
                l1 += d1 * d1
                axial += offset[i, a] * d0
            l0 = np.sqrt(l0)
            l1 = np.sqrt(l1)
            good = tracked[p] and tracked[c] and l1 > 1e-9
            axial /= l0
            # the offset with its component along the bone scaled by the bone's length ratio
            grow = axial * ((l1 / l0 if good else 1.0) - 1.0) / l0
            r = rot[bone[i]]
            for a in range(3):
                s = pos[p, a]
                for b in range(3):
                    s += r[a, b] * (offset[i, b] + grow * (bind[c, b] - bind[p, b]))
                q[i, a] = s
            ok[i] = good
        ok[i] = ok[i] and np.isfinite(q[i, 0]) and np.isfinite(q[i, 1]) and np.isfinite(q[i, 2])
        if not ok[i]:
            for a in range(3):
                q[i, a] = points[i, a]
    return ok
