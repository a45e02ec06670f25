"""The studio's face routes: the template for the page (GET /api/face/template) and the export of a face
take recorded in the page (POST /api/face/export → GLB), both from kinetre.face so page and CLI agree."""
from __future__ import annotations

import asyncio
import base64
import tempfile
from pathlib import Path

import numpy as np
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from ..errors import KinetreError
from ..face.caricature import NAMES, PRESETS, morph_targets, weights_from
from ..face.template import load_template

MAX_FRAMES = 1800  # a minute at 30 fps: the GLB holds one morph target per frame


def template_payload() -> dict:
    t = load_template()
    return {"vertices": t.vertices.ravel().round(5).tolist(), "uvs": t.uvs.ravel().round(6).tolist(),
            "triangles": t.triangles.ravel().tolist(), "weights": t.weights.tolist(),
            "mirror": t.mirror.tolist(), "chin": t.chin, "noseTip": t.nose_tip,
            "morphNames": list(NAMES), "morphs": morph_targets().reshape(len(NAMES), -1).round(5).tolist(),
            "presets": {k: weights_from(v).tolist() for k, v in PRESETS.items()}}


def export_face(body: dict) -> bytes:
    """GLB bytes of a face take: {width, height, fps, frames: [468·3 numbers | null], weights, image, turn}."""
    from ..face.export import write_face_gltf
    from ..face.pipeline import face_from_landmarks
    try:
        width, height, fps = int(body["width"]), int(body["height"]), float(body.get("fps", 30))
        raw = body["frames"]
        if not isinstance(raw, list) or not 0 < len(raw) <= MAX_FRAMES:
            raise KinetreError(f"face take: between 1 and {MAX_FRAMES} frames, got {len(raw) if isinstance(raw, list) else raw!r}")
        frames = [None if f is None else np.asarray(f, dtype=float).reshape(-1, 3) for f in raw]
        image = base64.b64decode(body["image"], validate=True)
        weights = np.asarray(body.get("weights", [0.0] * len(NAMES)), dtype=float).reshape(len(NAMES))
    except (KeyError, TypeError, ValueError) as e:
        raise KinetreError(f"face take: malformed request ({e})") from None
    if not image.startswith(b"\xff\xd8"):
        raise KinetreError("face take: the texture must be a base64 JPEG image")
    take = face_from_landmarks(frames, width, height, image, "image/jpeg", fps, turn=bool(body.get("turn")))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "face.glb"
        write_face_gltf(path, take.frames, take.image, take.mime, take.fps, weights)
        return path.read_bytes()


async def template_get(request: Request) -> Response:
    return JSONResponse(template_payload())


async def export_post(request: Request) -> Response:
    try:
        body = await request.json()
        glb = await asyncio.get_running_loop().run_in_executor(None, export_face, body)
    except KinetreError as e:
        return JSONResponse({"error": str(e)}, 400)
    except ValueError as e:
        return JSONResponse({"error": f"face take: not JSON ({e})"}, 400)
    return Response(glb, media_type="model/gltf-binary",
                    headers={"Content-Disposition": 'attachment; filename="kinetre-face.glb"'})


def face_routes() -> list[Route]:
    return [Route("/api/face/template", template_get),
            Route("/api/face/export", export_post, methods=["POST"])]
