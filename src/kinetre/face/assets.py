"""The canonical face mesh, read out of MediaPipe's `face_landmarker.task` model bundle.

The `.task` file is a zip archive of the FaceLandmarker's TFLite models and one
`geometry_pipeline_metadata_landmarks.binarypb`, a `GeometryPipelineMetadata` protobuf
(mediapipe/modules/face_geometry/protos/geometry_pipeline_metadata.proto):

    1 canonical_mesh             Mesh3d { 1 vertex_type enum (0 = VERTEX_PT: x y z u v),
                                          2 primitive_type enum (0 = TRIANGLE),
                                          3 vertex_buffer repeated float, 4 index_buffer repeated uint32 }
    2 procrustes_landmark_basis  repeated { 1 landmark_id uint32, 2 weight float }
    3 input_source               enum

(repeated scalars may come packed or one per field; both are read). The same file, byte for byte, is in
the legacy Face Mesh solution's assets.

The wire format is read by hand below (varints, fixed32 and length-delimited fields are all it uses).
Regenerate the shipped template with (default model: `kinetre.motion.models.model_path`)

    python -m kinetre.face.assets -o src/kinetre/data/face_template.json [--task face_landmarker.task]
"""
from __future__ import annotations

import argparse
import json
import sys
import zipfile
from pathlib import Path

import numpy as np

from ..errors import KinetreError
from ..motion.models import model_path, sha256_of

MODEL = "face_landmarker.task"
METADATA = "geometry_pipeline_metadata_landmarks.binarypb"
CHIN = 152        # MediaPipe's chin landmark: the lowest vertex on the face's midline (the paper's anchor)
NOSE_TIP = 1


class BadAssetError(KinetreError):
    """The model bundle is missing or does not hold the expected canonical mesh."""


def bundled_file(task: Path, name: str = METADATA) -> bytes:
    """The bytes of one file of the `.task` bundle at `task`."""
    try:
        with zipfile.ZipFile(task) as bundle:
            return bundle.read(name)
    except FileNotFoundError:
        raise BadAssetError(f"{task}: no such model file") from None
    except KeyError:
        raise BadAssetError(f"{task}: the model bundle holds no {name}") from None
    except (zipfile.BadZipFile, OSError) as e:
        raise BadAssetError(f"{task}: not a .task model bundle ({e})") from None


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


def extract(task: Path | None = None) -> dict:
    """The template as shipped in src/kinetre/data/face_template.json (plain lists, 6 decimals), from the
    model bundle `task` (default: the verified `face_landmarker.task`)."""
    task = model_path(MODEL) if task is None else Path(task)
    meta = parse_metadata(bundled_file(task))
    return {
        "source": f"{task.name} (sha256 {sha256_of(task.read_bytes())}): {METADATA} (Apache-2.0)",
        "units": "cm",
        "chin": CHIN,
        "nose_tip": NOSE_TIP,
        "vertices": np.round(meta["vertices"], 6).tolist(),
        "uvs": np.round(meta["uvs"], 6).tolist(),
        "triangles": meta["triangles"].tolist(),
        "procrustes_weights": np.round(meta["procrustes_weights"], 6).tolist(),
        "mirror": mirror_permutation(meta["vertices"]).tolist(),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", type=Path, default=None, help=f"the {MODEL} bundle (default: the verified copy)")
    parser.add_argument("-o", "--output", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        template = extract(args.task)
        args.output.write_text(json.dumps(template, separators=(",", ":")) + "\n", encoding="utf-8")
    except KinetreError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"error: {args.output}: cannot write ({e.strerror})", file=sys.stderr)
        return 2
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
