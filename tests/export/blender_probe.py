"""Run inside Blender (`blender -b --factory-startup --python blender_probe.py -- JOB.json OUT.json`): import
each file of the job with Blender's own importers, record what Blender evaluates at the asked frames, and
round-trip glTF files through Blender's own exporter. Coordinates are given back in glTF/BVH axes (+Y up).

JOB: {"fps": 30, "gltf": [{"path", "frames", "export"}], "bvh": [{"path", "frames"}]}
OUT: {"gltf": [{"meshes": {name: {"rest": V x 3, "frames": F x V x 3}}}], "bvh": [{"joints": {name: F x 3}}]}
"""
import builtins
import json
import sys

import numpy as np

np.bool = bool        # Blender 3.4's glTF importer still calls np.bool, which numpy 1.24 removed
import bpy            # noqa: E402

Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])     # Blender's +Z up back to +Y up


def fresh_scene(fps):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    # the importers turn seconds into frames at the scene's rate: at Blender's default 24 a 30 fps take resamples
    bpy.context.scene.render.fps = fps
    bpy.context.scene.render.fps_base = 1.0


def coords(vertices, matrix):
    flat = np.empty(3 * len(vertices))
    vertices.foreach_get("co", flat)
    local = flat.reshape(-1, 3)
    m = np.array(matrix)
    return ((local @ m[:3, :3].T + m[:3, 3]) @ Y_UP.T).tolist()


def probe_gltf(job, fps):
    fresh_scene(fps)
    bpy.ops.import_scene.gltf(filepath=job["path"])
    scene = bpy.context.scene
    meshes = {o.name: {"rest": coords(o.data.vertices, o.matrix_world), "frames": []}
              for o in scene.objects if o.type == "MESH"}
    for frame in job["frames"]:
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for o in scene.objects:
            if o.type != "MESH":
                continue
            evaluated = o.evaluated_get(depsgraph)
            mesh = evaluated.to_mesh()
            meshes[o.name]["frames"].append(coords(mesh.vertices, evaluated.matrix_world))
            evaluated.to_mesh_clear()
    if job.get("export"):
        bpy.ops.export_scene.gltf(filepath=job["export"], export_format="GLB")
    return {"meshes": meshes}


def probe_bvh(job, fps):
    fresh_scene(fps)
    # Blender 3.4's BVH importer opens the file in mode "rU", which Python 3.11 removed
    from io_anim_bvh import import_bvh
    import_bvh.open = lambda path, mode="r", *a, **k: builtins.open(path, mode.replace("U", ""), *a, **k)
    bpy.ops.import_anim.bvh(filepath=job["path"], global_scale=1.0, frame_start=1, use_fps_scale=False,
                            update_scene_fps=False, update_scene_duration=True)
    scene = bpy.context.scene
    armature = next(o for o in scene.objects if o.type == "ARMATURE")
    joints = {b.name: [] for b in armature.pose.bones}
    for frame in job["frames"]:
        scene.frame_set(1 + frame)          # the file's first frame is Blender's frame 1
        m = np.array(armature.matrix_world)
        for b in armature.pose.bones:
            joints[b.name].append(((m[:3, :3] @ np.array(b.head) + m[:3, 3]) @ Y_UP.T).tolist())
    return {"joints": joints, "fps": scene.render.fps}


def main():
    args = sys.argv[sys.argv.index("--") + 1:]
    with open(args[0]) as f:
        job = json.load(f)
    out = {"gltf": [probe_gltf(j, job["fps"]) for j in job.get("gltf", [])],
           "bvh": [probe_bvh(j, job["fps"]) for j in job.get("bvh", [])]}
    with open(args[1], "w") as f:
        json.dump(out, f)


main()
