"""Takes: the frames a scene solved while recording, exported as files a person can take away.

A take is written as GLB (the mesh animated), node transforms (the page replays its physics from them),
and, when a user drove it, BVH and the skeleton stream of its first user, with that user's hands and face
blendshapes as `kinetre capture` records a person's (so `kinetre avatar` drives fingers and expressions from
it). Each take gets a folder of its own under the studio's take directory, served as /api/takes/<id>/<file>.
Every mesh that moved is written, each the same way: mesh N's files as `take-mesh<N>.*`, listed under its
entry of "meshes" by kind ("glb", "transforms", "bvh", "stream") and all together in "files" as "glb-N", ….
"""
from __future__ import annotations

import asyncio
import itertools
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

from ..errors import KinetreError
from ..motion.take import PersonFrame, Take, crowd_take
from ..skeleton.mediapipe import BLENDSHAPES
from .scene import Scene, TakeFrame, resample

TAKE_FPS = 30.0


class Takes:
    """The folders of one studio's takes, by id (removed with `close`)."""

    def __init__(self):
        self.dir = Path(tempfile.mkdtemp(prefix="kinetre-takes-"))
        self._ids = itertools.count(1)

    def new(self) -> tuple[int, Path]:
        take_id = next(self._ids)
        return take_id, self.folder(take_id)

    def folder(self, take_id: int) -> Path:
        folder = self.dir / str(int(take_id))
        folder.mkdir(parents=True, exist_ok=True)
        return folder

    def file(self, take_id: int, name: str) -> Path | None:
        """A take's file by its name (no path parts), or None."""
        path = self.dir / str(int(take_id)) / Path(name).name
        return path if path.is_file() else None

    def close(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)


async def record_take(scene: Scene, takes: Takes, fps: float = TAKE_FPS) -> dict:
    """Stop the scene's recording and export the take; {"take", "frames", "fps", "files": {"kind-id": url},
    "meshes": [{"id", "name", "frames", "files": {kind: url}}]} (every mesh that moved, in the scene's order)."""
    recorded = {i: resample(frames, fps) for i, frames in scene.stop_recordings().items()}
    recorded = {i: take for i, take in recorded.items() if take and i in scene.meshes}
    if not recorded:
        raise KinetreError("the take is empty: possess the mesh (or play the sample) while recording")
    take_id, folder = takes.new()
    files, meshes = {}, []
    for mesh_id, take in recorded.items():
        m = scene.meshes[mesh_id]
        clients = list(take[0].skeletons)
        applied = scene.users.applied(clients[0]) if clients else None  # the skeletons were cleaned as solved
        written = await asyncio.to_thread(export_take, folder, m.mesh, m.graph, take, fps, f"take-mesh{mesh_id}",
                                          applied)
        urls = {kind: f"/api/takes/{take_id}/{name}" for kind, name in written.items()}
        files.update({f"{kind}-{mesh_id}": url for kind, url in urls.items()})
        meshes.append({"id": mesh_id, "name": m.name, "frames": len(take), "files": urls})
    return {"take": take_id, "frames": max(m["frames"] for m in meshes), "fps": fps, "files": files,
            "meshes": meshes}


def export_take(folder: Path, mesh, graph, take, fps: float, stem: str = "take",
                applied: dict | None = None) -> dict[str, str]:
    """Write the take as GLB (the mesh animated), node transforms (physics replay), BVH and the skeleton
    stream of its first user, as `stem`.glb and so on; `applied`: what cleaned that user's frames (the
    stream's header records it, so nothing cleans them again)."""
    from ..export.gltf import write_gltf
    files = {}
    write_gltf(folder / f"{stem}.glb", mesh, graph, [f.pose for f in take], fps)
    files["glb"] = f"{stem}.glb"
    from ..physics.take import write_take_transforms  # the page replays the physics from these
    write_take_transforms(folder / f"{stem}.transforms", graph, [f.pose for f in take], fps)
    files["transforms"] = f"{stem}.transforms"
    clients = [c for c in take[0].skeletons]
    if clients:
        first = [f for f in take if f.skeletons.get(clients[0]) is not None]
        frames = [f.skeletons[clients[0]] for f in first]
        from ..export.bvh import write_bvh
        write_bvh(folder / f"{stem}.bvh", frames, fps)
        files["bvh"] = f"{stem}.bvh"
        from ..motion import stream
        stream.write_stream(folder / f"{stem}.kinetre.jsonl",
                            replace(user_take(first, clients[0], fps), applied=applied))
        files["stream"] = f"{stem}.kinetre.jsonl"
    return files


def user_take(frames: list[TakeFrame], client: str, fps: float) -> Take:
    """User `client`'s skeleton frames as a take; with the hands and blendshapes the user sent, as a camera
    take's person 0 (the main person), in the layout `kinetre capture` writes."""
    main = [f.skeletons[client] for f in frames]
    if not any(client in f.hands or client in f.blendshapes for f in frames):
        return Take.from_frames(main, fps)
    people = [(PersonFrame(0, f.skeletons[client], f.hands.get(client), f.blendshapes.get(client)),) for f in frames]
    return crowd_take(main, people, fps, "", BLENDSHAPES)
