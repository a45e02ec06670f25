"""The studio's HTTP routes: scene state, meshes and their upload jobs, voice commands, takes, joint maps.

    GET  /api/state            the scene state (JSON)
    GET  /api/mesh/{id}        one of the scene's meshes with its skinning data (JSON, base64 arrays)
    POST /api/mesh/up?up=AXIS  stand the first mesh (&mesh=ID: that one) with that stored axis (y, z, x, -x,
                               -y, -z) up (the page's override of the up axis found on load, mesh/upright.py):
                               a job like an upload
    POST /api/mesh?name=F      upload a mesh file (OBJ/PLY/STL/GLB…): a job that loads it and builds the graph;
                               it replaces the first mesh, or with &add=1 joins the scene beside the others;
                               a .zip of RGB-D frames (TUM or Redwood layout) is scanned into a mesh first
                               (&segment=plane|none, &voxel=metres)
    DELETE /api/mesh/{id}      remove a mesh (its possessors let go); the scene keeps at least one
    GET  /api/jobs/{id}        a job's stage, progress fraction, readable error and, once done, its mesh id
    POST /api/voice?client=C   16 kHz mono WAV: recognised offline, "possess"/"release"/subset applied for C
                               (&mesh=ID: "possess" takes that mesh)
    POST /api/record/start     start recording a take; /api/record/stop ends it and exports GLB, BVH, stream
                               and the node transforms the page replays the physics from
    GET  /api/takes/{id}/{f}   a file of a recorded take
    POST /api/motion?name=F    play a motion file (BVH, glTF/GLB, VRM Animation .vrma, a Kinetre take) in a loop as
                               the sample motion, which possesses the mesh as the sample does
    POST /api/jointmap?name=F  a joint map (JSON, docs/joint-maps.md): the n-th user to possess drives with the
                               joints its n-th source keeps; DELETE /api/jointmap clears it
"""
from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Callable

from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Route

from ..errors import KinetreError
from .channels import Channels
from .host import SceneHost, apply
from .jobs import MAX_UPLOAD
from .scene import MeshError
from .uploads import read_upload


def query_mesh(request: Request) -> int | None:
    """The request's `mesh` query parameter (a mesh id), None without one; MeshError (400) if not an id."""
    value = request.query_params.get("mesh")
    if value is None or value == "":
        return None
    if not value.isdigit() or int(value) < 1:
        raise MeshError(f"mesh must be a mesh id (a positive integer), got {value!r}")
    return int(value)


def refused(exc: KinetreError) -> JSONResponse:
    """A refused request: 404 for a mesh the scene does not hold, else 400."""
    return JSONResponse({"error": str(exc)}, getattr(exc, "status", 400))


def api_routes(host: SceneHost, hub: Channels, connected: Callable[[str], bool]) -> list[Route]:
    """The routes around `host`; `connected(client)` says whether a page of that name is connected."""

    async def state(request: Request) -> Response:
        return JSONResponse(host.state())

    async def mesh_get(request: Request) -> Response:
        payload = await host.mesh_json(int(request.path_params["mesh_id"]))
        if payload is None:
            return JSONResponse({"error": f"mesh {request.path_params['mesh_id']} is not loaded"}, 404)
        return Response(payload, media_type="application/json")

    async def mesh_post(request: Request) -> Response:
        add = request.query_params.get("add", "0")
        if add not in ("0", "1"):
            return JSONResponse({"error": f"add must be 0 (replace the first mesh) or 1 (add one), got {add!r}"},
                                400)
        name, data, too_big = await read_upload(request, "mesh", MAX_UPLOAD)
        if too_big is not None:
            return too_big
        scan_options = {}
        if name.lower().endswith(".zip"):  # the "Scan" entry: RGB-D frames, segmented by plane by default
            segment = request.query_params.get("segment", "plane")
            if segment not in ("plane", "none"):
                return JSONResponse({"error": f"{name}: segment must be 'plane' or 'none', got {segment!r}"}, 400)
            try:
                voxel = float(request.query_params.get("voxel", "0.01"))
            except ValueError:
                return JSONResponse({"error": f"{name}: voxel must be a number in metres"}, 400)
            scan_options = {"segment": None if segment == "none" else segment, "voxel": voxel}
        job = host.start_job(name, data, scan_options, add=add == "1")
        return JSONResponse({"job": job.id}, 202)

    async def mesh_up(request: Request) -> Response:
        try:
            job = host.set_up(request.query_params.get("up", ""), query_mesh(request))
        except KinetreError as exc:
            return refused(exc)
        return JSONResponse({"job": job.id}, 202)

    async def mesh_delete(request: Request) -> Response:
        mesh_id = int(request.path_params["mesh_id"])
        try:
            await host.remove_mesh(mesh_id)
        except KinetreError as exc:
            return refused(exc)
        return JSONResponse({"removed": mesh_id})

    async def job_get(request: Request) -> Response:
        job = host.jobs.get(int(request.path_params["job_id"]))
        if job is None:
            return JSONResponse({"error": "no such job"}, 404)
        return JSONResponse({"job": job.id, "name": job.name, **job.status(),
                             "mesh": job.mesh_id if job.done and not job.error else None})

    voice_decoder: dict = {}

    async def voice_post(request: Request) -> Response:
        client = request.query_params.get("client", "")
        try:
            mesh = query_mesh(request)
        except KinetreError as exc:
            return refused(exc)
        data = await request.body()
        from .voice import Recogniser, recognise
        try:
            # one decoder for the studio's lifetime: loading it again for every utterance would add to each one
            if voice_decoder.get("recogniser") is None:
                voice_decoder["recogniser"] = await asyncio.to_thread(Recogniser)
        except KinetreError as exc:  # pocketsphinx missing: the page says how to install it
            return JSONResponse({"error": str(exc)}, 503)
        try:
            command = await asyncio.to_thread(recognise, data, 16000, recogniser=voice_decoder["recogniser"])
        except KinetreError as exc:
            return JSONResponse({"error": str(exc)}, 400)
        if command is None:
            return JSONResponse({"command": None})
        result = {"verb": command.verb, "subset": command.subset, "text": command.text}
        if connected(client):
            if command.verb == "possess":
                msg = {"type": "possess", "subset": command.subset, "mesh": mesh}
            elif command.verb == "release":
                msg = {"type": "release"}
            elif command.subset is not None:
                msg = {"type": "subset", "subset": command.subset}
            else:
                msg = None
            if msg is not None:  # as if the page had sent it: an error reaches the page on its connection
                await apply(host, hub, client, msg, json.dumps(msg).encode())
        return JSONResponse({"command": result})

    async def record_start(request: Request) -> Response:
        host.start_recording()
        return JSONResponse({"recording": True})

    async def record_stop(request: Request) -> Response:
        try:
            return JSONResponse(await host.stop_recording())
        except KinetreError as exc:
            return JSONResponse({"error": str(exc)}, 400)

    async def take_get(request: Request) -> Response:
        name, take_id = request.path_params["name"], int(request.path_params["take_id"])
        path = host.takes.file(take_id, name)
        if path is None:
            return JSONResponse({"error": f"no file {name} in take {take_id}"}, 404)
        return FileResponse(path, filename=f"kinetre-{take_id}-{path.name}")

    async def motion_post(request: Request) -> Response:
        name, data, too_big = await read_upload(request, "motion", MAX_UPLOAD)
        if too_big is not None:
            return too_big
        try:
            return JSONResponse(await host.play_motion(name, data))
        except KinetreError as exc:
            return JSONResponse({"error": str(exc)}, 400)

    async def joint_map(request: Request) -> Response:
        from ..motion.jointmap import parse_joint_map
        try:
            if request.method == "DELETE":
                chosen = None
            else:
                name = Path(request.query_params.get("name", "joint map")).name
                try:
                    chosen = parse_joint_map(json.loads(await request.body()), name)
                except ValueError as exc:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
                    return JSONResponse({"error": f"{name}: not valid JSON ({exc})"}, 400)
            return JSONResponse({"joint_map": host.set_joint_map(chosen)})
        except KinetreError as exc:
            return JSONResponse({"error": str(exc)}, 400)

    return [
        Route("/api/jointmap", joint_map, methods=["POST", "DELETE"]),
        Route("/api/state", state),
        Route("/api/mesh/{mesh_id:int}", mesh_get),
        Route("/api/mesh/{mesh_id:int}", mesh_delete, methods=["DELETE"]),
        Route("/api/mesh", mesh_post, methods=["POST"]),
        Route("/api/mesh/up", mesh_up, methods=["POST"]),
        Route("/api/jobs/{job_id:int}", job_get),
        Route("/api/voice", voice_post, methods=["POST"]),
        Route("/api/motion", motion_post, methods=["POST"]),
        Route("/api/record/start", record_start, methods=["POST"]),
        Route("/api/record/stop", record_stop, methods=["POST"]),
        Route("/api/takes/{take_id:int}/{name}", take_get),
    ]
