"""A take as a rigged, animated glTF 2.0 file: graph nodes become joints, one animation.

The static part of a mesh without material (positions, normals, indices, vertex colours) is written here
with pygltflib; a mesh with UVs or a material (and its embedded image) goes through trimesh's glTF exporter.
The skin and the animation are added with pygltflib:

* every graph node j is a joint node with rest translation g_j and inverse bind matrix translate(-g_j);
* per frame its translation is g_j + t_j and its rotation the polar-decomposition rotation Q_j of R_j, so
  a glTF player computes  v' = sum_j w_j (Q_j (v - g_j) + g_j + t_j),  which differs from our own skinning
  (Eq. 2, with R_j) only by the small non-rotation part of R_j (< 0.1 % of the bbox diagonal on the test clips);
* JOINTS_0 / WEIGHTS_0 are the graph's 4 nodes and weights per vertex (Eq. 2);
* one animation, one LINEAR sampler pair (translation, rotation) per joint, keyed at every frame.

When a take stretches the mesh (a badly fitting skeleton pulls nodes apart), dropping the non-rotation part
of R_j can cost more than that 0.1 %. Then each joint gets a parent node that carries it exactly:
R_j = U diag(s) W (SVD), parent translation g_j + t_j, rotation U and scale s, joint rotation W, so the
joint's world matrix is T(g_j + t_j) R_j and the player's skinning equals Eq. 2 at every key
(`stretch=None` picks this only when needed, from `polar_error_bound`).
"""
from __future__ import annotations

import base64
import dataclasses
import json
import struct
from pathlib import Path

import numpy as np
import pygltflib as gl

from ..deform.pose import GraphPose
from ..errors import ExportError
from ..graph.graph import DeformationGraph
from ..jit import njit
from ..lazy import import_trimesh
from ..mesh.mesh import Mesh, column_bounds
from ..rotation import matrix_quaternions
from ..svd3 import det3, svd3

_ALIGN = 4  # glTF: every bufferView starts on a 4-byte boundary


def write_gltf(path, mesh: Mesh, graph: DeformationGraph, poses: list[GraphPose], fps: float,
               name: str = "take", *, stretch: bool | None = None, tolerance: float = 1e-3) -> None:
    """Write `mesh`, rigged by `graph` and animated by `poses`, as .glb (binary) or .gltf (one JSON file).

    Parameters
    ----------
    path : str or Path
        Output file; the extension picks the container (".glb" or ".gltf", the latter with its buffer
        embedded as a data URI so it is a single file).
    mesh : Mesh
        The mesh as loaded; its UVs, normals, vertex colours and material are written where present.
    graph : DeformationGraph
        Graph built on `mesh` (vertex_nodes / vertex_weights have one row per mesh vertex).
    poses : list of GraphPose
        One pose per frame (N rotations (N, 3, 3) and translations (N, 3) each); at least one.
    fps : float
        Frames per second of the take: frame k is keyed at time k / fps.
    name : str
        Name of the animation (and prefix of the mesh and joint names).
    stretch : bool or None
        False: plain joints (translation + polar rotation), which drop the non-rotation part of each
        R_j. True: each joint gets a parent node carrying R_j's stretch (R_j = U diag(s) W: parent
        rotation U and scale s, joint rotation W), so a player reproduces Eq. 2 exactly at every key.
        None (default): True only if dropping the stretch could move a vertex by more than `tolerance`
        times the bounding-box diagonal (`polar_error_bound`).
    tolerance : float
        See `stretch`.

    Raises
    ------
    ExportError
        Unknown extension, empty take, mismatched sizes, non-finite poses, or an unwritable path.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".glb", ".gltf"):
        raise ExportError(f"{path}: a glTF file must end in .glb or .gltf, got {ext or 'no extension'!r}")
    rotations, translations = _check_take(path, mesh, graph, poses, fps)

    if mesh.uvs is None and mesh.material is None:
        doc, blob = geometry_document(mesh, name)
    else:
        doc, blob = exported_document(path, mesh, name)
        if mesh.uvs is not None and mesh.colors is not None:
            # trimesh's TextureVisuals carry no colours: add COLOR_0 ourselves (normalised unsigned bytes)
            doc.meshes[0].primitives[0].attributes.COLOR_0 = append_accessor(
                doc, blob, _rgba(mesh.colors), gl.VEC4, gl.UNSIGNED_BYTE, normalized=True, minmax=True,
                target=gl.ARRAY_BUFFER)
    svd = svd3(rotations)  # one factorisation serves the bound and either kind of joint
    if stretch is None:
        stretch = polar_error_bound(mesh, graph, rotations, svd[1]) > tolerance * mesh.diagonal
    _add_skin_and_animation(doc, blob, graph, rotations, translations, fps, name, bool(stretch), svd)
    save_gltf(path, doc, blob, "Kinetre (embedded deformation export, trimesh + pygltflib)")


def save_gltf(path: Path, doc: gl.GLTF2, blob: bytes, generator: str, binary: bool | None = None) -> None:
    """Write `doc` with `blob` as its one buffer: .glb binary, or .gltf with the buffer as a data URI
    (`binary` overrides the choice by extension, for binary glTF under its own name such as .vrma).

    The JSON is serialised here rather than by pygltflib's `save_binary`, which deep-copies every value of
    the document and re-packs the buffer view by view (over a second for a 400k-vertex take); the buffer
    views already index `blob` as it is.
    """
    doc.buffers = [gl.Buffer(byteLength=len(blob))]
    doc.asset = gl.Asset(version="2.0", generator=generator)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.suffix.lower() == ".glb" if binary is None else binary:
            text = _document_json(doc)
            text += b" " * (-len(text) % _ALIGN)  # chunks start on 4-byte boundaries
            pad = b"\0" * (-len(blob) % _ALIGN)
            with open(path, "wb") as fh:
                fh.write(struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(blob) + len(pad)))
                fh.write(struct.pack("<I4s", len(text), b"JSON") + text)
                fh.write(struct.pack("<I4s", len(blob) + len(pad), b"BIN\0"))
                fh.write(blob)
                fh.write(pad)
        else:
            doc.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
            path.write_bytes(_document_json(doc))
    except OSError as err:
        raise ExportError(f"{path}: cannot write the glTF file ({err.strerror or err})") from None


def _document_json(doc: gl.GLTF2) -> bytes:
    """The glTF JSON of a pygltflib document: its fields as plain values, None and empty ones left out (as
    pygltflib writes them)."""
    return json.dumps(_plain(doc, True), separators=(",", ":"), allow_nan=False,
                      default=_json_scalar).encode("utf-8")


_FIELDS: dict[type, tuple[str, ...]] = {}
_LEAVES = (int, float, str, bool, type(None))


def _plain(value, prune: bool):
    """pygltflib dataclasses (and their Attributes) → dicts and lists, without copying leaf values, in one pass
    with what `pygltflib.delete_empty_keys` then does: where `prune`, a dict leaves out the keys whose value
    is None or empty, and so do the dicts below it, except inside "extensions" and in lists of lists."""
    kind = type(value)
    if kind in _LEAVES:
        return value
    if kind in (list, tuple):
        return [_plain(v, prune and type(v) not in (list, tuple)) for v in value]
    if kind is gl.Attributes or kind is dict:
        items = (value.__dict__ if kind is gl.Attributes else value).items()
    else:
        names = _FIELDS.get(kind)
        if names is None:
            if not dataclasses.is_dataclass(value):
                return value
            names = _FIELDS.setdefault(kind, tuple(f.name for f in dataclasses.fields(value)))
        items = ((name, getattr(value, name)) for name in names)
    if not prune:
        return {k: _plain(v, False) for k, v in items}
    out = {}
    for k, v in items:
        v = _plain(v, k != "extensions")
        if v is None or (hasattr(v, "__iter__") and len(v) == 0):
            continue
        out[k] = v
    return out


def _json_scalar(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not a glTF JSON value")


def polar_rotations(matrices: np.ndarray, svd=None) -> np.ndarray:
    """The rotation factor Q of the polar decomposition M = Q S of each matrix.

    Parameters
    ----------
    matrices : (..., 3, 3) float64
        Near-rotations R_j.
    svd : tuple, optional
        `svd3(matrices)` when the caller has it already.

    Returns
    -------
    (..., 3, 3) float64
        Proper rotations (det +1) closest to each matrix in the Frobenius norm (Q = U V^T from the SVD,
        with the last singular direction flipped where det(U V^T) < 0).

    >>> q = polar_rotations(np.diag([2.0, 1.0, 0.5])[None])
    >>> bool(np.allclose(q, np.eye(3)))
    True
    """
    u, _, vt = svd3(matrices) if svd is None else svd
    d = np.sign(det3(u) * det3(vt))
    d[d == 0] = 1.0
    u = u.copy()
    u[..., :, 2] *= d[..., None]
    return u @ vt


def rotation_quaternions(rotations: np.ndarray) -> np.ndarray:
    """(F, N, 3, 3) rotations -> (F, N, 4) float32 unit quaternions (x, y, z, w), sign-continuous in time.

    Consecutive keys of one joint are kept in the same hemisphere (q and -q are the same rotation), so a
    player's slerp between keys never takes the long way round.
    """
    q = matrix_quaternions(rotations)
    f = rotations.shape[0]
    for k in range(1, f):
        flip = np.einsum("nd,nd->n", q[k], q[k - 1]) < 0
        q[k, flip] *= -1.0
    return q.astype(np.float32)


def _check_take(path, mesh, graph, poses, fps):
    """Validate sizes and values; return the stacked (F, N, 3, 3) rotations and (F, N, 3) translations."""
    if not poses:
        raise ExportError(f"{path}: the take has no frames to export")
    if not np.isfinite(fps) or fps <= 0:
        raise ExportError(f"{path}: fps must be a positive number, got {fps}")
    v, n = mesh.vertices.shape[0], graph.node_count
    if graph.vertex_nodes.shape != (v, 4) or graph.vertex_weights.shape != (v, 4):
        raise ExportError(f"{path}: the graph skins {graph.vertex_nodes.shape[0]} vertices but the mesh has {v}")
    if n >= 65536:
        raise ExportError(f"{path}: {n} graph nodes; glTF joints are limited to 65535")
    rotations = np.stack([np.asarray(p.rotations, dtype=np.float64) for p in poses])
    translations = np.stack([np.asarray(p.translations, dtype=np.float64) for p in poses])
    if rotations.shape != (len(poses), n, 3, 3) or translations.shape != (len(poses), n, 3):
        raise ExportError(f"{path}: poses must hold ({n}, 3, 3) rotations and ({n}, 3) translations, "
                          f"got {rotations.shape[1:]} and {translations.shape[1:]}")
    bad = ~(np.isfinite(rotations).all(axis=(1, 2, 3)) & np.isfinite(translations).all(axis=(1, 2)))
    if bad.any():
        raise ExportError(f"{path}: pose of frame {int(np.argmax(bad))} is not finite")
    return rotations, translations


def geometry_document(mesh: Mesh, name: str) -> tuple[gl.GLTF2, bytearray]:
    """The document and buffer of a mesh without UVs or material: indices, positions, normals and vertex
    colours, as trimesh's exporter writes them (accessor bounds included) but without its export and
    pygltflib's re-parse of it (0.12-0.18 s at 386k vertices)."""
    doc, blob = gl.GLTF2(scene=0), bytearray()  # the default scene, as trimesh's document names it
    attributes = gl.Attributes()
    indices = append_accessor(doc, blob, np.asarray(mesh.faces).reshape(-1).astype(np.uint32), gl.SCALAR, gl.UNSIGNED_INT,
                      minmax=True, target=gl.ELEMENT_ARRAY_BUFFER)
    attributes.POSITION = append_accessor(doc, blob, np.asarray(mesh.vertices, dtype=np.float32), gl.VEC3, gl.FLOAT,
                                  minmax=True, target=gl.ARRAY_BUFFER)
    if mesh.colors is not None:
        attributes.COLOR_0 = append_accessor(doc, blob, _rgba(mesh.colors), gl.VEC4, gl.UNSIGNED_BYTE, normalized=True,
                                     minmax=True, target=gl.ARRAY_BUFFER)
    attributes.NORMAL = append_accessor(doc, blob, np.asarray(mesh.normals, dtype=np.float32), gl.VEC3, gl.FLOAT,
                                minmax=True, target=gl.ARRAY_BUFFER)
    doc.meshes = [gl.Mesh(name=name, primitives=[gl.Primitive(attributes=attributes, indices=indices,
                                                               mode=gl.TRIANGLES)])]
    return doc, blob


def _rgba(colors) -> np.ndarray:
    """(V, 4) uint8 vertex colours; RGB gets an opaque alpha (as trimesh's ColorVisuals does)."""
    colors = np.asarray(colors, dtype=np.uint8)
    if colors.shape[1] == 3:
        colors = np.concatenate([colors, np.full((len(colors), 1), 255, np.uint8)], axis=1)
    return np.ascontiguousarray(colors)


def exported_document(path, mesh: Mesh, name: str) -> tuple[gl.GLTF2, bytearray]:
    """The document and buffer of the mesh alone (no nodes kept), exported by trimesh and parsed back by
    pygltflib: the way for UVs and materials (images embedded, material kinds converted to PBR)."""
    trimesh = import_trimesh()
    visual = None
    if mesh.uvs is not None:
        material = mesh.material if mesh.material is not None else trimesh.visual.material.PBRMaterial(
            baseColorFactor=[200, 200, 200, 255])
        visual = trimesh.visual.TextureVisuals(uv=np.asarray(mesh.uvs, dtype=np.float64), material=material)
    elif mesh.colors is not None:
        visual = trimesh.visual.ColorVisuals(vertex_colors=np.asarray(mesh.colors, dtype=np.uint8))
    elif mesh.material is not None:
        # a material without UVs: keep its colour factors, drop any image (it could not be mapped)
        pbr = mesh.material.to_pbr() if hasattr(mesh.material, "to_pbr") else mesh.material
        factor = getattr(pbr, "baseColorFactor", None)
        visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
            baseColorFactor=factor if factor is not None else [200, 200, 200, 255],
            metallicFactor=getattr(pbr, "metallicFactor", None), roughnessFactor=getattr(pbr, "roughnessFactor", None)))
    static = trimesh.Trimesh(vertices=np.asarray(mesh.vertices, dtype=np.float64),
                             faces=np.asarray(mesh.faces, dtype=np.int64),
                             vertex_normals=np.asarray(mesh.normals, dtype=np.float64), visual=visual,
                             process=False, validate=False)
    try:
        doc = gl.GLTF2.load_from_bytes(static.export(file_type="glb", include_normals=True))
    except Exception as err:  # trimesh's exporter raises many kinds (bad image, bad material)
        raise ExportError(f"{path}: cannot encode the mesh as glTF ({type(err).__name__}: {err})") from None
    if len(doc.meshes) != 1 or len(doc.meshes[0].primitives) != 1:
        raise ExportError(f"{path}: expected one mesh primitive from the exporter, got {len(doc.meshes)} meshes")
    prim = doc.meshes[0].primitives[0]
    if doc.accessors[prim.attributes.POSITION].count != mesh.vertices.shape[0]:
        raise ExportError(f"{path}: the exporter changed the vertex count, so the skin would not match")
    # trimesh leaves bufferView targets out (a validator hint): vertex data and indices are known here
    for attr in ("POSITION", "NORMAL", "TEXCOORD_0", "COLOR_0"):
        index = getattr(prim.attributes, attr)
        if index is not None:
            doc.bufferViews[doc.accessors[index].bufferView].target = gl.ARRAY_BUFFER
    doc.bufferViews[doc.accessors[prim.indices].bufferView].target = gl.ELEMENT_ARRAY_BUFFER
    doc.meshes[0].name = name
    doc.nodes, doc.scenes, doc.scene = [], [], 0
    return doc, bytearray(doc.binary_blob() or b"")


def append_accessor(doc: gl.GLTF2, blob: bytearray, array: np.ndarray, gltf_type: str, component: int,
                    normalized: bool = False, minmax: bool = False, target: int | None = None) -> int:
    """Append `array` to the buffer as a new bufferView + accessor; return the accessor index."""
    blob.extend(b"\0" * (-len(blob) % _ALIGN))
    data = np.ascontiguousarray(array)
    doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=data.nbytes, target=target))
    blob += memoryview(data).cast("B")  # one copy, into the buffer (tobytes would make another)
    acc = gl.Accessor(bufferView=len(doc.bufferViews) - 1, byteOffset=0, componentType=component,
                      normalized=normalized or None, count=int(array.shape[0]), type=gltf_type)
    if minmax:
        acc.min, acc.max = column_bounds(array)
    doc.accessors.append(acc)
    return len(doc.accessors) - 1


def skin_weights(graph: DeformationGraph) -> tuple[np.ndarray, np.ndarray]:
    """glTF-ready JOINTS_0 (V, 4) uint16/uint8 and WEIGHTS_0 (V, 4) float32 from the graph.

    Weights are renormalised in float32 so each row sums to 1 as closely as float32 allows (the
    validator's tolerance), and a joint slot with zero weight is pointed at the row's first joint, so no
    joint index repeats with a non-zero weight.
    """
    joints = np.empty(graph.vertex_nodes.shape, np.uint8 if graph.node_count < 256 else np.uint16)
    weights = np.empty(graph.vertex_weights.shape, np.float32)
    # the graph's own float32 weights and int32 nodes go in as they are (the kernel widens each weight to
    # float64, exactly): converting the (V, 4) tables first cost 40 ms at 386k vertices
    w_in, nodes = np.ascontiguousarray(graph.vertex_weights), np.ascontiguousarray(graph.vertex_nodes)
    if w_in.dtype not in (np.float32, np.float64):
        w_in = w_in.astype(np.float64)
    if nodes.dtype not in (np.int32, np.int64):
        nodes = nodes.astype(np.int64)
    bad = _skin_weights(w_in, nodes, joints, weights)
    if bad:
        raise ExportError(f"graph: {bad} vertices have no positive skinning weight")
    return joints, weights


@njit(cache=True)
def _skin_weights(w_in, nodes, joints, w32):
    """`skin_weights` row by row (one pass instead of a dozen (V, 4) temporaries); the sums run in numpy's
    order for a row of 4, so the result is bit for bit numpy's clip / normalise / float32 / residual-on-the-
    largest. Returns the number of rows whose total weight is not positive and finite."""
    bad = 0
    w = np.empty(w_in.shape[1])
    for v in range(w_in.shape[0]):
        total = 0.0
        for q in range(w.shape[0]):
            x = w_in[v, q]
            w[q] = 0.0 if x < 0.0 else x  # np.clip(x, 0, None): NaN stays NaN
            total += w[q]
        if not (total > 0.0 and np.isfinite(total)):
            bad += 1
            continue
        big = 0
        for q in range(w.shape[0]):
            w32[v, q] = np.float32(w[q] / total)
            if w32[v, q] > w32[v, big]:
                big = q
        # the float32 rounding error goes on the largest weight
        w32[v, big] = 0.0
        rest = w32[v, 0]
        for q in range(1, w.shape[0]):
            rest += w32[v, q]
        w32[v, big] = np.float32(1.0) - rest
        for q in range(w.shape[0]):
            joints[v, q] = nodes[v, big] if w32[v, q] == 0 else nodes[v, q]
    return bad


def polar_error_bound(mesh: Mesh, graph: DeformationGraph, rotations: np.ndarray,
                      singular_values: np.ndarray | None = None) -> float:
    """Upper bound on how far any vertex moves when each R_j is replaced by its polar rotation Q_j.

    |sum_j w_j (R_j - Q_j)(v - g_j)| <= max_j ||R_j - Q_j||_2 * r_j, with r_j the largest distance from
    node j to a vertex it influences (the weights are convex).

    Parameters
    ----------
    rotations : (F, N, 3, 3) float64
    singular_values : (F, N, 3) float64, optional
        Their singular values, when the caller has them already.

    Returns
    -------
    float, in the mesh's units.
    """
    reach = _reach(np.ascontiguousarray(mesh.vertices, dtype=np.float64), np.ascontiguousarray(graph.nodes),
                   np.ascontiguousarray(graph.vertex_nodes), np.ascontiguousarray(graph.vertex_weights))
    # R − Q = U (diag(s) − diag(1, 1, d)) V^T with d = sign det R: its 2-norm is max_i |s_i − e_i|
    # (where det R = 0, s_3 = 0 and |s_3 − d| = 1 for either sign)
    s = svd3(rotations)[1] if singular_values is None else singular_values  # (F, N, 3)
    d = np.where(det3(rotations) < 0, -1.0, 1.0)
    gap = np.maximum(np.abs(s[..., :2] - 1.0).max(axis=-1), np.abs(s[..., 2] - d))            # (F, N)
    return float((gap * reach[None]).max())


@njit(cache=True)
def _reach(vertices, nodes, indices, weights):
    """(N,) per node, the largest distance to a vertex it moves with a positive weight."""
    reach = np.zeros(nodes.shape[0])
    for v in range(vertices.shape[0]):
        for q in range(indices.shape[1]):
            if weights[v, q] > 0:
                j = indices[v, q]
                dx = vertices[v, 0] - nodes[j, 0]
                dy = vertices[v, 1] - nodes[j, 1]
                dz = vertices[v, 2] - nodes[j, 2]
                reach[j] = max(reach[j], np.sqrt(dx * dx + dy * dy + dz * dz))
    return reach


def stretch_factors(rotations: np.ndarray, svd=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """R = U diag(s) W per node and frame, with U, W proper rotations chosen continuous in time.

    Parameters
    ----------
    rotations : (F, N, 3, 3) float64
    svd : tuple, optional
        `svd3(rotations)` when the caller has it already (its arrays are modified).

    Returns
    -------
    u, w : (F, N, 3, 3) rotations; s : (F, N, 3) scales (the singular values, the last one negative
    where det R < 0).

    Notes
    -----
    The SVD is unique only up to a signed permutation M of the singular directions (U M, M^T diag M,
    M^T W): of the 24 proper ones, each frame takes the M nearest to the previous frame's factors, so a
    player interpolating between keys does not swing through a relabelling of the axes.
    """
    u, s, w = svd3(rotations) if svd is None else svd
    # make U and W proper; a reflection in R (det < 0) goes into the last scale
    du, dw = np.sign(det3(u)), np.sign(det3(w))
    du[du == 0], dw[dw == 0] = 1.0, 1.0
    u[..., :, 2] *= du[..., None]
    w[..., 2, :] *= dw[..., None]
    s[..., 2] *= du * dw
    u, s, w = (np.ascontiguousarray(x, dtype=np.float64) for x in (u, s, w))
    _follow_previous(u, s, w, _proper_signed_permutations())
    return u, s, w


@njit(cache=True)
def _follow_previous(u, s, w, cube):
    """`stretch_factors`' frame-to-frame choice, in place: for k = 1, 2, ... each node's U, s, W of frame k
    taken through the signed permutation M of `cube` (24, 3, 3) nearest to frame k - 1's as already taken.

    Closeness <U', U M> + <W', Mᵀ W> = <Uᵀ U' + W W'ᵀ, M> (Frobenius), the first largest of the 24. A product
    by a signed permutation picks one entry per sum and adds exact zeros, so U M, Mᵀ W and diag(Mᵀ diag(s) M)
    here are numpy's matrix products to the bit, signed zeros included (a sum of zeros is -0 only when every
    term is, in any order)."""
    near = np.empty((3, 3))
    for k in range(1, u.shape[0]):
        for n in range(u.shape[1]):
            for a in range(3):
                for b in range(3):
                    near[a, b] = (u[k, n, 0, a] * u[k - 1, n, 0, b] + u[k, n, 1, a] * u[k - 1, n, 1, b]
                                  + u[k, n, 2, a] * u[k - 1, n, 2, b]) + \
                                 (w[k, n, a, 0] * w[k - 1, n, b, 0] + w[k, n, a, 1] * w[k - 1, n, b, 1]
                                  + w[k, n, a, 2] * w[k - 1, n, b, 2])
            best, pick = -np.inf, 0
            for c in range(cube.shape[0]):
                score = 0.0
                for a in range(3):
                    for b in range(3):
                        score += near[a, b] * cube[c, a, b]
                if score > best:
                    best, pick = score, c
            m = cube[pick]
            uk, wk, sk = u[k, n].copy(), w[k, n].copy(), s[k, n].copy()
            for a in range(3):
                for b in range(3):
                    u[k, n, a, b] = uk[a, 0] * m[0, b] + uk[a, 1] * m[1, b] + uk[a, 2] * m[2, b]
                    w[k, n, a, b] = m[0, a] * wk[0, b] + m[1, a] * wk[1, b] + m[2, a] * wk[2, b]
                s[k, n, a] = m[0, a] * m[0, a] * sk[0] + m[1, a] * m[1, a] * sk[1] + m[2, a] * m[2, a] * sk[2]


def _proper_signed_permutations() -> np.ndarray:
    """The 24 rotations that map coordinate axes to coordinate axes (signed permutation matrices)."""
    import itertools

    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[list(perm), range(3)] = signs
            if np.linalg.det(m) > 0:
                out.append(m)
    return np.array(out)


def _add_skin_and_animation(doc, blob, graph, rotations, translations, fps, name, stretch, svd):
    f, n = translations.shape[:2]
    prim = doc.meshes[0].primitives[0]
    joints, weights = skin_weights(graph)
    prim.attributes.JOINTS_0 = append_accessor(doc, blob, joints, gl.VEC4,
                                       gl.UNSIGNED_BYTE if joints.dtype == np.uint8 else gl.UNSIGNED_SHORT,
                                       target=gl.ARRAY_BUFFER)
    prim.attributes.WEIGHTS_0 = append_accessor(doc, blob, weights, gl.VEC4, gl.FLOAT, target=gl.ARRAY_BUFFER)

    g = np.asarray(graph.nodes, dtype=np.float64)
    # node 0: the skinned mesh (a root without transform, as glTF requires for skinned meshes)
    # node 1: the rig root, parent of every joint, so the joints share a common root
    # then per graph node j, at rest translated to g_j: the joint "node_j"; with stretch, the joint is
    # the child of "node_j_stretch" (translation g_j + t_j, rotation U, scale s) and rotates by W
    step = 2 if stretch else 1
    top = [2 + step * j for j in range(n)]
    joint_ids = [t + step - 1 for t in top]
    doc.nodes = [gl.Node(name=name, mesh=0, skin=0), gl.Node(name=f"{name}_graph", children=top)]
    for j in range(n):
        rest = [float(x) for x in g[j]]
        if stretch:
            doc.nodes += [gl.Node(name=f"node_{j}_stretch", translation=rest, children=[joint_ids[j]]),
                          gl.Node(name=f"node_{j}")]
        else:
            doc.nodes.append(gl.Node(name=f"node_{j}", translation=rest))
    inverse_bind = np.tile(np.eye(4, dtype=np.float32), (n, 1, 1))
    inverse_bind[:, :3, 3] = -g
    # glTF matrices are column-major: store the transpose of each row-major matrix
    ibm = append_accessor(doc, blob, inverse_bind.transpose(0, 2, 1).reshape(n, 16), gl.MAT4, gl.FLOAT)
    doc.skins = [gl.Skin(name=f"{name}_skin", joints=joint_ids, skeleton=1, inverseBindMatrices=ibm)]
    doc.scenes = [gl.Scene(name=name, nodes=[0, 1])]

    times = (np.arange(f, dtype=np.float64) / fps).astype(np.float32)
    time_acc = append_accessor(doc, blob, times, gl.SCALAR, gl.FLOAT, minmax=True)
    position = (g[None] + translations).astype(np.float32)              # (F, N, 3)
    tracks = []                                                          # (node, path, (F, k) values)
    if stretch:
        u, s, w = stretch_factors(rotations, svd)
        qu, qw = rotation_quaternions(u), rotation_quaternions(w)
        for j in range(n):
            tracks += [(top[j], "translation", position[:, j]), (top[j], "rotation", qu[:, j]),
                       (top[j], "scale", s[:, j].astype(np.float32)), (joint_ids[j], "rotation", qw[:, j])]
    else:
        quats = rotation_quaternions(polar_rotations(rotations, svd))     # (F, N, 4)
        for j in range(n):
            tracks += [(top[j], "translation", position[:, j]), (top[j], "rotation", quats[:, j])]
    samplers, channels = [], []
    for node, prop, values in tracks:
        acc = append_accessor(doc, blob, values, gl.VEC4 if prop == "rotation" else gl.VEC3, gl.FLOAT)
        samplers.append(gl.AnimationSampler(input=time_acc, output=acc, interpolation="LINEAR"))
        channels.append(gl.AnimationChannel(sampler=len(samplers) - 1,
                                            target=gl.AnimationChannelTarget(node=node, path=prop)))
    doc.animations = [gl.Animation(name=name, samplers=samplers, channels=channels)]
