"""The scene's state message: what every page shows of the scene (its meshes, users, take and counters)."""
from __future__ import annotations

import numpy as np

from .meshes import Meshes, SceneMesh
from .users import Users


def mesh_state(m: SceneMesh) -> dict:
    """One mesh as the state lists it (with "attached", its possessors' attached joints by client)."""
    attached = {c: np.asarray(j).tolist() for c, j in zip(m.possessors, m.attached)} if m.rig is not None else {}
    return {"id": m.id, "name": m.name, "url": f"/api/mesh/{m.id}", "nodes": m.graph.node_count,
            "vertices": int(len(m.mesh.vertices)), "up": m.upright.up if m.upright else "y",
            "up_reason": m.upright.reason if m.upright else "", "placement": m.placement.as_dict(),
            "possessors": list(m.possessors) if m.rig is not None else [],
            "solve_ms": float(np.median(m.solve_ms)) if m.solve_ms else None, "attached": attached}


def scene_state(meshes: Meshes, users: Users, recording: bool, joint_map, error: str, skipped: int) -> dict:
    """The state message. `skipped`: frames the skeleton subscription merged latest-wins."""
    listed = [mesh_state(m) for m in meshes.values()]
    attached = {c: j for mesh in listed for c, j in mesh.pop("attached").items()}
    solve_cpu = [ms for m in meshes.values() for ms in m.solve_cpu_ms]
    solve_ms = [ms for m in meshes.values() for ms in m.solve_ms]
    return {
        "type": "state",
        "meshes": listed,
        "users": [{"client": u.client, "possessing": u.bind is not None, "mesh": u.mesh, "subset": u.subset,
                   "hand": u.hand, "frames": u.frames, "attached": attached.get(u.client, []),
                   "cleaning": u.cleaning, "quality": None if u.meter is None else u.meter.figures()}
                  for u in users.values()],
        "recording": recording,
        "joint_map": None if joint_map is None else {"name": joint_map.path, "sources": len(joint_map.sources)},
        "solve_ms": float(np.median(solve_ms)) if solve_ms else None,
        "solve_cpu_ms": float(np.median(solve_cpu)) if solve_cpu else None,
        "solve_cpu_ms_p99": float(np.percentile(solve_cpu, 99)) if solve_cpu else None,
        "solves_stopped": sum(m.stopped for m in meshes.values()),
        "error": error,
        # frames in: all that reached the scene; merged: superseded before a solve used them (in the
        # subscription's slot or as a user's newest frame); late: older than the user's newest
        "skeleton_frames": users.frames_in + skipped,
        "dropped": {"merged": users.superseded + skipped, "late": users.late},
    }
