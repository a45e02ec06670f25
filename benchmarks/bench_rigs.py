"""Any rig drives any mesh: glTF animation sampling, the shape fit, and `kinetre animate` with Fox.glb#Walk.

One JSON object per line:
  {"bench": "gltf_sample", "animation", "joints", "frames", "ms", "frames_per_s"}   every Fox animation at 30 fps
  {"bench": "fit_shapes", "mesh", "vertices", "ms", "inside", "cpu_ms"}              Fox#Walk into each mesh
  {"bench": "animate_gltf", "mesh", "frames", "total_s", ...stage seconds, "attached"} the whole command
On a shared machine compare cpu_ms / cpu_s with the wall times.
"""
from __future__ import annotations

import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

import kinetre
from kinetre.cli import build_parser
from kinetre.cli.animate import cmd_animate
from kinetre.motion.align import fit_shapes
from kinetre.motion.gltf import animations, load_gltf

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
FOX = DATA / "avatars" / "Fox.glb"
MESHES = ("spot.obj", "armadillo.obj")


def main() -> None:
    for info in animations(FOX):
        start = time.perf_counter()
        take = load_gltf(FOX, info.name, fps=30.0, as_kinect=False)
        ms = 1000 * (time.perf_counter() - start)
        print(json.dumps({"bench": "gltf_sample", "animation": info.name, "joints": len(take.model.joints),
                          "frames": len(take), "ms": round(ms, 1),
                          "frames_per_s": round(len(take) / ms * 1000, 1)}), flush=True)
    walk = load_gltf(FOX, "Walk")
    for name in MESHES:
        mesh = kinetre.load_mesh(DATA / "meshes" / name)
        wall, cpu = time.perf_counter(), time.process_time()
        fit = fit_shapes(walk, mesh)
        print(json.dumps({"bench": "fit_shapes", "mesh": name, "vertices": len(mesh.vertices),
                          "ms": round(1000 * (time.perf_counter() - wall), 1), "inside": round(fit.inside, 3),
                          "cpu_ms": round(1000 * (time.process_time() - cpu), 1)}), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in MESHES:
            args = build_parser().parse_args(["animate", str(DATA / "meshes" / name), "--motion", f"{FOX}#Walk",
                                              "-o", str(Path(tmp) / "out.glb")])
            stats: dict = {}
            out = io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
                cmd_animate(args, stats)
            attached = next((line.split()[1] for line in out.getvalue().splitlines() if line.startswith("attached")),
                            "?")
            record = {"bench": "animate_gltf", "mesh": name, "vertices": stats["vertices"], "nodes": stats["nodes"],
                      "frames": stats["frames"], "attached_joints": int(attached) if attached.isdigit() else None}
            record.update({k: round(v, 2) for k, v in stats.items() if k.endswith("_s")})
            print(json.dumps(record), flush=True)


if __name__ == "__main__":
    main()
