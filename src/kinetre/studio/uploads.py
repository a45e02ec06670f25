"""An uploaded file's body, refused when empty or over the size cap (meshes, scans and avatars alike)."""
from __future__ import annotations

from starlette.requests import Request
from starlette.responses import JSONResponse


async def read_upload(request: Request, default_name: str, limit: int) -> tuple[str, bytes, JSONResponse | None]:
    """(name from `?name=`, body, None), or (name, body, the error response to send) when it is refused."""
    name = request.query_params.get("name", default_name)
    data = await request.body()
    if not data:
        return name, data, JSONResponse({"error": f"{name}: the file is empty"}, 400)
    if len(data) > limit:
        return name, data, JSONResponse({"error": f"{name}: {len(data) >> 20} MB is over the {limit >> 20} MB limit"},
                                        413)
    return name, data, None
