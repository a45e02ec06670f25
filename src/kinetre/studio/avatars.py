"""Avatars in the studio: uploaded rigged humanoids, their bone maps and plans, and their recorded takes.

    POST /api/avatar?name=F                  upload a .glb/.gltf/.vrm: 200 {avatar payload} when enough maps to
                                             drive it (hips, torso, a limb; "missing" lists the joints that then
                                             follow their parents); 422 {error, missing, avatar payload with the
                                             partial map} when too little maps (the page's map editor completes
                                             it); 400 {error} when it is no humanoid (the page then offers it for
                                             possession)
    GET  /api/avatars/{id}/file              the avatar file (the page loads it with three.js)
    POST /api/avatars/{id}/map               {"kinect20": {Kinect joint: avatar joint name}}: saved as JSON next to
                                             the avatar (used from then on), the plan recomputed
    GET  /api/avatars/{id}/map               that JSON file, to keep next to one's own copy of the avatar
    POST /api/avatars/{id}/takes             {fps, positions (T x 20 x 3, null = untracked), tracked, and optional
                                             hands (T x [left, right]) and blendshapes (T x 52), each frame's as a
                                             skeleton message has them (protocol.py), or null}: the frames that
                                             drove the avatar, retargeted again here and exported as GLB (finger
                                             rotations and morph-weight tracks too) + BVH
    GET  /api/avatars/{id}/takes/{n}/{file}  a file of such a take

The page retargets live in TypeScript with the plan it gets here (the same numbers, see
tests/avatar/test_page_retarget.py); the server maps the bones and writes the files.
"""
from __future__ import annotations

import asyncio
import itertools
import re
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Route

from ..avatar.bonemap import auto_map, can_drive, check_humanoid, map_path, parse_map, write_map
from ..avatar.load import EXTENSIONS, load_avatar
from ..avatar.retarget import plan_retarget, retarget
from ..errors import BadAvatarError, KinetreError
from ..motion.take import Take
from ..skeleton.mediapipe import BLENDSHAPES
from ..skeleton.models import KINECT20
from .protocol import ProtocolError, parse_blendshapes, parse_hands
from .uploads import read_upload

MAX_AVATAR = 100 * 1024 * 1024
TAKE_FPS_LIMITS = (1.0, 240.0)


@dataclass
class Shelf:
    """The avatars uploaded to one studio, each in its own folder (where its map JSON is saved)."""

    folder: Path = field(default_factory=lambda: Path(tempfile.mkdtemp(prefix="kinetre-avatars-")))
    avatars: dict = field(default_factory=dict)
    _ids: itertools.count = field(default_factory=lambda: itertools.count(1))
    _takes: itertools.count = field(default_factory=lambda: itertools.count(1))

    def add(self, name: str, data: bytes) -> tuple[int, dict]:
        """Store and map an uploaded avatar: (HTTP status, body)."""
        base = Path(name).name or "avatar.glb"
        if not base.lower().endswith(EXTENSIONS):
            return 400, {"error": f"{base}: an avatar must be a rigged .glb, .gltf or .vrm file"}
        avatar_id = next(self._ids)
        path = self.folder / str(avatar_id) / base
        path.parent.mkdir(parents=True)
        path.write_bytes(data)
        try:
            avatar = load_avatar(path)
        except BadAvatarError as exc:
            return 400, {"error": self._public(exc)}
        self.avatars[avatar_id] = {"id": avatar_id, "name": base, "path": path, "avatar": avatar}
        return self.remap(avatar_id)

    def remap(self, avatar_id: int) -> tuple[int, dict]:
        entry = self.avatars[avatar_id]
        avatar = entry["avatar"]
        bonemap = auto_map(avatar)
        entry["bonemap"], entry["plan"] = bonemap, None
        body = self.payload(avatar_id)
        if not can_drive(bonemap):
            return 422, {**body, "error": f"{entry['name']}: too little of the skeleton maps to drive it (no joint "
                                          f"found for {', '.join(bonemap.missing)}): pick them in the avatar map"}
        try:
            check_humanoid(avatar, bonemap)
        except BadAvatarError as exc:
            self.avatars.pop(avatar_id)
            return 400, {"error": self._public(exc)}
        entry["plan"] = plan_retarget(avatar, bonemap)
        return 200, self.payload(avatar_id)

    def payload(self, avatar_id: int) -> dict:
        entry = self.avatars[avatar_id]
        avatar, bonemap, plan = entry["avatar"], entry["bonemap"], entry["plan"]
        return {"id": avatar_id, "name": entry["name"], "url": f"/api/avatars/{avatar_id}/file",
                "joints": list(avatar.joint_names), "nodes": [int(n) for n in avatar.joints],
                "map": {k: int(v) for k, v in bonemap.joints.items()}, "how": bonemap.how,
                "missing": list(bonemap.missing), "plan": plan.to_json() if plan is not None else None}

    def save_map(self, avatar_id: int, table: dict) -> tuple[int, dict]:
        entry = self.avatars[avatar_id]
        joints = parse_map(table, entry["avatar"], entry["name"])
        write_map(map_path(str(entry["path"])), entry["avatar"], joints)
        return self.remap(avatar_id)

    def export(self, avatar_id: int, body: dict) -> dict:
        """Retarget the frames that drove the avatar in the page and write take.glb + take.bvh."""
        from ..avatar.export import write_avatar_bvh, write_avatar_gltf
        entry = self.avatars[avatar_id]
        if entry["plan"] is None:
            raise BadAvatarError(f"{entry['name']}: complete the avatar map before recording")
        fps = body.get("fps")
        if not isinstance(fps, (int, float)) or not TAKE_FPS_LIMITS[0] <= fps <= TAKE_FPS_LIMITS[1]:
            raise BadAvatarError(f"fps must be a number in {TAKE_FPS_LIMITS}, got {fps!r}")
        rows, flags = body.get("positions"), body.get("tracked")
        if not isinstance(rows, list) or not rows or not isinstance(flags, list) or len(flags) != len(rows):
            raise BadAvatarError("the take needs frames: positions (T x 20 x 3) and tracked (T x 20)")
        try:
            pos = np.array([[[np.nan] * 3 if p is None else p for p in frame] for frame in rows], dtype=np.float64)
            tracked = np.array(flags, dtype=bool)
        except (TypeError, ValueError):
            raise BadAvatarError("positions must be numbers or null, tracked booleans") from None
        if pos.shape != (len(rows), 20, 3) or tracked.shape != (len(rows), 20):
            raise BadAvatarError(f"expected {len(rows)} x 20 x 3 positions and {len(rows)} x 20 flags, got "
                                 f"{pos.shape} and {tracked.shape}")
        motion = retarget(entry["plan"], pos, tracked)
        hands = _per_frame(body.get("hands"), len(rows), parse_hands, "hands")
        faces = _per_frame(body.get("blendshapes"), len(rows), parse_blendshapes, "blendshapes")
        morphs = None
        if hands is not None or faces is not None:
            from ..avatar.drive import hands_and_face
            take = Take(KINECT20, pos, tracked, float(fps), entry["name"], (0,), pos[:, None], tracked[:, None],
                        None if hands is None else hands[:, None], None if faces is None else faces[:, None],
                        BLENDSHAPES if faces is not None else ())
            motion, morphs = hands_and_face(entry["avatar"], entry["bonemap"], entry["plan"], motion, take)
        take = next(self._takes)
        folder = entry["path"].parent / "takes" / str(take)
        folder.mkdir(parents=True)
        write_avatar_gltf(folder / "take.glb", entry["avatar"], motion, float(fps), morph_weights=morphs)
        write_avatar_bvh(folder / "take.bvh", entry["avatar"], entry["plan"], motion, float(fps))
        base = f"/api/avatars/{avatar_id}/takes/{take}"
        return {"take": take, "frames": len(rows), "fps": fps,
                "files": {"glb": f"{base}/take.glb", "bvh": f"{base}/take.bvh"}}

    def _public(self, exc: Exception) -> str:
        """The message without the server's folders (the user knows the file by its name)."""
        return re.sub(re.escape(str(self.folder)) + r"/\d+/", "", str(exc))

    def close(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


def _per_frame(rows, count: int, parse, name: str) -> np.ndarray | None:
    """A take's per-frame hands or blendshapes (`parse` reads one frame's, None for null) stacked, NaN where a
    frame has none; None when no frame has any."""
    if rows is None:
        return None
    if not isinstance(rows, list) or len(rows) != count:
        raise BadAvatarError(f"{name} must list one entry (or null) for each of the {count} frames")
    frames = []
    for k, row in enumerate(rows):
        try:
            frames.append(parse(row))
        except ProtocolError as exc:
            raise BadAvatarError(f"frame {k}: {exc}") from None
    shape = next((f.shape for f in frames if f is not None), None)
    if shape is None:
        return None
    return np.stack([np.full(shape, np.nan) if f is None else f for f in frames])


def avatar_routes(shelf: Shelf) -> list[Route]:
    """The routes of the module docstring, bound to `shelf`."""

    def entry(request: Request):
        return shelf.avatars.get(int(request.path_params["avatar_id"]))

    async def upload(request: Request) -> Response:
        name, data, refused = await read_upload(request, "avatar.glb", MAX_AVATAR)
        if refused is not None:
            return refused
        status, body = await asyncio.to_thread(shelf.add, name, data)
        return JSONResponse(body, status)

    async def file(request: Request) -> Response:
        found = entry(request)
        if found is None:
            return JSONResponse({"error": "no such avatar"}, 404)
        return FileResponse(found["path"], media_type="model/gltf-binary")

    async def save_map(request: Request) -> Response:
        found = entry(request)
        if found is None:
            return JSONResponse({"error": "no such avatar"}, 404)
        if request.method == "GET":
            saved = Path(map_path(str(found["path"])))
            if not saved.is_file():
                return JSONResponse({"error": f"{found['name']}: no map saved yet"}, 404)
            return FileResponse(saved, media_type="application/json", filename=saved.name)
        try:
            body = await request.json()
            table = body.get("kinect20") if isinstance(body, dict) else None
            if not isinstance(table, dict):
                raise BadAvatarError('the map must be {"kinect20": {Kinect joint: avatar joint}}')
            status, out = await asyncio.to_thread(shelf.save_map, found["id"], table)
        except ValueError:
            return JSONResponse({"error": "the map is not JSON"}, 400)
        except KinetreError as exc:
            return JSONResponse({"error": shelf._public(exc)}, 400)
        return JSONResponse(out, status)

    async def take_post(request: Request) -> Response:
        found = entry(request)
        if found is None:
            return JSONResponse({"error": "no such avatar"}, 404)
        try:
            body = await request.json()
            if not isinstance(body, dict):
                raise BadAvatarError("the take must be a JSON object")
            return JSONResponse(await asyncio.to_thread(shelf.export, found["id"], body))
        except ValueError:
            return JSONResponse({"error": "the take is not JSON"}, 400)
        except KinetreError as exc:
            return JSONResponse({"error": shelf._public(exc)}, 400)

    async def take_get(request: Request) -> Response:
        found = entry(request)
        name = Path(request.path_params["name"]).name
        if found is None:
            return JSONResponse({"error": "no such avatar"}, 404)
        path = found["path"].parent / "takes" / str(int(request.path_params["take"])) / name
        if not path.is_file():
            return JSONResponse({"error": f"no file {name} in that take"}, 404)
        return FileResponse(path, filename=f"kinetre-avatar-{found['id']}-{request.path_params['take']}-{name}")

    return [
        Route("/api/avatar", upload, methods=["POST"]),
        Route("/api/avatars/{avatar_id:int}/file", file),
        Route("/api/avatars/{avatar_id:int}/map", save_map, methods=["GET", "POST"]),
        Route("/api/avatars/{avatar_id:int}/takes", take_post, methods=["POST"]),
        Route("/api/avatars/{avatar_id:int}/takes/{take:int}/{name}", take_get),
    ]
