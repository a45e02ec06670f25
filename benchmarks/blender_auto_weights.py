"""Run inside Blender (`blender -b --factory-startup --python blender_auto_weights.py -- JOB.json OUT.npz`):
Blender's one-click automatic weights on a rigged glTF, against its artist skin.

The file is imported with Blender's glTF importer at the job's frame rate; every clip is evaluated at the
asked times with the artist skin; then each skinned mesh loses its vertex groups and armature modifier and
is parented to the armature with ARMATURE_AUTO (bone heat), and every clip is evaluated again.
Coordinates are given back in glTF axes (+Y up), world space.

JOB: {"path": str, "fps": float, "clips": [{"animation": index, "name": str, "times": [seconds]}]}
OUT: artist_K and auto_K, (F, V, 3) for clip K, the meshes' vertices concatenated in object-name order.
"""
import json
import sys

import numpy as np

np.bool = bool        # Blender 3.4's glTF importer still calls np.bool, which numpy 1.24 removed
import bpy            # noqa: E402

Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])     # Blender's +Z up back to +Y up


def evaluated(meshes):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = []
    for o in meshes:
        e = o.evaluated_get(depsgraph)
        mesh = e.to_mesh()
        flat = np.empty(3 * len(mesh.vertices))
        mesh.vertices.foreach_get("co", flat)
        m = np.array(e.matrix_world)
        out.append((flat.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]) @ Y_UP.T)
        e.to_mesh_clear()
    return np.concatenate(out)


def action_of(armature, clip, actions):
    """The action the importer made for the clip's glTF animation (it names them after the animation)."""
    name = clip["name"]
    for a in actions:
        if a.name == name or a.name.startswith(name + "_") or a.name.startswith(name + "."):
            return a
    return actions[min(clip["animation"], len(actions) - 1)]


def play(armature, meshes, clips, actions, fps):
    out = []
    scene = bpy.context.scene
    for clip in clips:
        armature.animation_data.action = action_of(armature, clip, actions)
        frames = []
        for t in clip["times"]:
            f = t * fps
            scene.frame_set(int(np.floor(f)), subframe=float(f - np.floor(f)))
            frames.append(evaluated(meshes))
        out.append(np.stack(frames))
    return out


def main():
    args = sys.argv[sys.argv.index("--") + 1:]
    with open(args[0]) as f:
        job = json.load(f)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    # the importer turns seconds into frames at the scene's rate
    scene.render.fps = int(round(job["fps"]))
    scene.render.fps_base = scene.render.fps / job["fps"]
    bpy.ops.import_scene.gltf(filepath=job["path"])
    fps = scene.render.fps / scene.render.fps_base
    armature = next(o for o in scene.objects if o.type == "ARMATURE")
    meshes = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name)
    if armature.animation_data is None:
        armature.animation_data_create()
    actions = list(bpy.data.actions)
    artist = play(armature, meshes, job["clips"], actions, fps)

    # one click: drop the artist's weights, parent with automatic weights (in the rest pose)
    armature.animation_data.action = None
    for bone in armature.pose.bones:
        bone.location, bone.scale = (0, 0, 0), (1, 1, 1)
        bone.rotation_quaternion, bone.rotation_euler = (1, 0, 0, 0), (0, 0, 0)
    bpy.ops.object.select_all(action="DESELECT")
    for o in meshes:
        for mod in [m for m in o.modifiers if m.type == "ARMATURE"]:
            o.modifiers.remove(mod)
        o.vertex_groups.clear()
        o.select_set(True)
    armature.select_set(True)
    bpy.context.view_layer.objects.active = armature
    bpy.ops.object.parent_set(type="ARMATURE_AUTO", keep_transform=True)
    auto = play(armature, meshes, job["clips"], actions, fps)
    np.savez(args[1], **{f"artist_{k}": a for k, a in enumerate(artist)},
             **{f"auto_{k}": a for k, a in enumerate(auto)})


main()
