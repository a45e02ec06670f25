"""Run inside Blender (`blender -b --factory-startup --python fbx_probe.py -- JOB.json OUT.json`): import each FBX
with Blender's own importer and record every mesh's evaluated vertices (world, +Y up) at the asked frames.

JOB: {"fps": 30, "fbx": [{"path", "frames"}]}    OUT: {"fbx": [{"frames": F x V x 3, "bones": n}]}
"""
import json
import sys

import numpy as np

import bpy

Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])


def evaluated(objects):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = []
    for o in objects:
        e = o.evaluated_get(depsgraph)
        mesh = e.to_mesh()
        flat = np.empty(3 * len(mesh.vertices))
        mesh.vertices.foreach_get("co", flat)
        m = np.array(e.matrix_world)
        out.append((flat.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]) @ Y_UP.T)
        e.to_mesh_clear()
    return np.concatenate(out)


def probe(job, fps):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = fps, 1.0
    bpy.ops.import_scene.fbx(filepath=job["path"], anim_offset=0.0)  # FBX time 0 at frame 0, as glTF's
    meshes = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name)
    frames = []
    for frame in job["frames"]:
        scene.frame_set(frame)
        frames.append(evaluated(meshes).tolist())
    bones = sum(len(o.data.bones) for o in scene.objects if o.type == "ARMATURE")
    return {"frames": frames, "bones": bones}


def main():
    args = sys.argv[sys.argv.index("--") + 1:]
    with open(args[0]) as f:
        job = json.load(f)
    with open(args[1], "w") as f:
        json.dump({"fbx": [probe(j, job["fps"]) for j in job["fbx"]]}, f)


main()
