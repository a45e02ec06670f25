"""The canonical face mesh, read out of @mediapipe/face_mesh's packed assets (SPEC §6.2).

The npm package ships its files as one Emscripten bundle, `face_mesh_solution_packed_assets.data`, whose
table of contents (file name, start, end) sits in `face_mesh_solution_packed_assets_loader.js`. One of the
files, `geometry_pipeline_metadata_landmarks.binarypb`, is a `GeometryPipelineMetadata` protobuf
(mediapipe/modules/face_geometry/protos/geometry_pipeline_metadata.proto):

    1 canonical_mesh             Mesh3d { 1 vertex_type enum (0 = VERTEX_PT: x y z u v),
                                          2 primitive_type enum (0 = TRIANGLE),
                                          3 vertex_buffer repeated float, 4 index_buffer repeated uint32 }
    2 procrustes_landmark_basis  repeated { 1 landmark_id uint32, 2 weight float }
    3 input_source               enum

(repeated scalars may come packed or one per field; both are read).

The wire format is read by hand below (varints, fixed32 and length-delimited fields are all it uses).
Regenerate the shipped template with

    python -m kinetre.face.assets web/node_modules/@mediapipe/face_mesh -o src/kinetre/data/face_template.json
"""
from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from ..errors import KinetreError

METADATA = "geometry_pipeline_metadata_landmarks.binarypb"
CHIN = 152        # MediaPipe's chin landmark: the lowest vertex on the face's midline (the paper's anchor)
NOSE_TIP = 1


class BadAssetError(KinetreError):
    """The npm package's assets are missing or do not hold the expected canonical mesh."""


def packed_file(package: Path, name: str = METADATA) -> bytes:
    """The bytes of one file of the Emscripten bundle in `package` (the @mediapipe/face_mesh folder)."""
    loader = package / "face_mesh_solution_packed_assets_loader.js"
    data = package / "face_mesh_solution_packed_assets.data"
    if not loader.is_file() or not data.is_file():
        raise BadAssetError(f"{package}: not an @mediapipe/face_mesh package (no packed assets)")
    pattern = r'"filename":\s*"([^"]*)",\s*"start":\s*(\d+),\s*"end":\s*(\d+)'
    for filename, start, end in re.findall(pattern, loader.read_text(encoding="utf-8")):
        if filename.endswith("/" + name):
            return data.read_bytes()[int(start):int(end)]
    raise BadAssetError(f"{loader}: no {name} in the bundle's table of contents")


def _varint(buf: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        b = buf[i]
        i += 1
        value |= (b & 0x7F) << shift
        if b < 0x80:
            return value, i
        shift += 7


def fields(buf: bytes):
    """Yield (field number, wire type, value) of a protobuf message; value is an int or the raw bytes."""
    i = 0
    while i < len(buf):
        key, i = _varint(buf, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = _varint(buf, i)
        elif wire == 1:
            value, i = buf[i:i + 8], i + 8
        elif wire == 2:
            size, i = _varint(buf, i)
            value, i = buf[i:i + size], i + size
        elif wire == 5:
            value, i = buf[i:i + 4], i + 4
        else:
            raise BadAssetError(f"unsupported protobuf wire type {wire} (field {number})")
        yield number, wire, value


def _packed_varints(buf: bytes) -> list[int]:
    out, i = [], 0
    while i < len(buf):
        v, i = _varint(buf, i)
        out.append(v)
    return out


def parse_metadata(buf: bytes) -> dict:
    """Canonical mesh (vertices (468, 3) cm, uvs (468, 2), triangles (898, 3)) and Procrustes weights (468,)."""
    ids, weights, mesh = [], [], None
    for number, _, value in fields(buf):
        if number == 2:
            ref = {n: v for n, _, v in fields(value)}
            ids.append(ref.get(1, 0))
            weights.append(float(np.frombuffer(ref.get(2, b"\0\0\0\0"), "<f4")[0]))
        elif number == 1:
            mesh = value
    if mesh is None:
        raise BadAssetError(f"{METADATA}: no canonical_mesh")
    floats, indices = [], []
    for number, wire, value in fields(mesh):
        if number in (1, 2) and value != 0:
            raise BadAssetError(f"{METADATA}: canonical mesh is not VERTEX_PT triangles (field {number} = {value})")
        if number == 3:
            floats.append(np.frombuffer(value, "<f4"))
        elif number == 4:
            indices.extend(_packed_varints(value) if wire == 2 else [value])
    if not floats or sum(map(len, floats)) % 5:
        raise BadAssetError(f"{METADATA}: the canonical mesh's vertex buffer is not x y z u v rows")
    vertex_buffer = np.concatenate(floats).reshape(-1, 5)
    triangles = np.asarray(indices, dtype=np.int64).reshape(-1, 3)
    n = len(vertex_buffer)
    basis = np.zeros(n)
    basis[np.asarray(ids, dtype=np.int64)] = weights
    return {"vertices": vertex_buffer[:, :3].astype(float), "uvs": vertex_buffer[:, 3:].astype(float),
            "triangles": triangles, "procrustes_weights": basis}


def mirror_permutation(vertices: np.ndarray) -> np.ndarray:
    """perm[i] = the vertex at i's mirror image across the x = 0 plane (the face's left/right swap)."""
    mirrored = vertices * np.array([-1.0, 1.0, 1.0])
    d = np.linalg.norm(mirrored[:, None, :] - vertices[None, :, :], axis=2)
    perm = d.argmin(axis=1)
    if not np.array_equal(perm[perm], np.arange(len(perm))):
        raise BadAssetError("the canonical mesh is not left/right symmetric")
    return perm


def extract(package: Path) -> dict:
    """The template as shipped in src/kinetre/data/face_template.json (plain lists, 6 decimals)."""
    meta = parse_metadata(packed_file(package))
    return {
        "source": "@mediapipe/face_mesh " + json.loads((package / "package.json").read_text())["version"]
                  + " face_mesh_solution_packed_assets.data: " + METADATA + " (Apache-2.0)",
        "units": "cm",
        "chin": CHIN,
        "nose_tip": NOSE_TIP,
        "vertices": np.round(meta["vertices"], 6).tolist(),
        "uvs": np.round(meta["uvs"], 6).tolist(),
        "triangles": meta["triangles"].tolist(),
        "procrustes_weights": np.round(meta["procrustes_weights"], 6).tolist(),
        "mirror": mirror_permutation(meta["vertices"]).tolist(),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("package", type=Path, help="the node_modules/@mediapipe/face_mesh folder")
    parser.add_argument("-o", "--output", type=Path, required=True)
    args = parser.parse_args(argv)
    args.output.write_text(json.dumps(extract(args.package), separators=(",", ":")) + "\n", encoding="utf-8")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
