"""Run by Blender (`blender -b --factory-startup --python fbx_in_blender.py -- IN.glb OUT.fbx FPS`): import a
Kinetre glTF with Blender's importer and write it with Blender's FBX exporter, the take baked at FPS. The last
line starting `kinetre-fbx: ` on stdout says `ok` or why not."""
import sys

import numpy

if not hasattr(numpy, "bool"):  # Blender 3.4's glTF importer calls np.bool, which numpy 1.24 removed
    numpy.bool = bool

import bpy  # noqa: E402


def main():
    gltf, fbx, fps = sys.argv[sys.argv.index("--") + 1:][:3]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = round(float(fps)), round(float(fps)) / float(fps)
    bpy.ops.import_scene.gltf(filepath=gltf)
    ends = [o.animation_data.action.frame_range for o in scene.objects
            if o.animation_data is not None and o.animation_data.action is not None]
    if ends:
        scene.frame_start = int(min(r[0] for r in ends))
        scene.frame_end = int(max(r[1] for r in ends))
    # every frame keyed (no curve simplification), the armature as the FBX root, no leaf bones added
    bpy.ops.export_scene.fbx(filepath=fbx, use_selection=False, object_types={"ARMATURE", "MESH"},
                             add_leaf_bones=False, bake_anim=True, bake_anim_use_all_bones=True,
                             bake_anim_use_nla_strips=False, bake_anim_use_all_actions=False,
                             bake_anim_force_startend_keying=True, bake_anim_step=1.0,
                             bake_anim_simplify_factor=0.0, armature_nodetype="NULL")


try:
    main()
except Exception as e:  # noqa: BLE001 - reported in one line to the command that ran Blender
    print(f"kinetre-fbx: {type(e).__name__}: {' '.join(str(e).split())}", flush=True)
    sys.exit(1)
print("kinetre-fbx: ok", flush=True)
