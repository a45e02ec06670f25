"""Run inside Blender (`blender -b --factory-startup --python addon_probe.py -- JOB.json OUT.json`): install and
enable the Kinetre add-on zip through Blender's own operators, then drive its panel's operators on a mesh as a
user would, recording what Blender holds after each step. Coordinates are given back +Y up (Kinetre's axes).

JOB: {"zip", "mesh", "motion", "broken", "fps", "nodes", "frames": [...], "obj": where to write the mesh the
add-on sends, "shot": optional PNG of the possessed mesh}
"""
import json
import sys

import numpy as np

import bpy

Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])


def world(obj):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    flat = np.empty(3 * len(mesh.vertices))
    mesh.vertices.foreach_get("co", flat)
    m = np.array(evaluated.matrix_world)
    out = (flat.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]) @ Y_UP.T
    evaluated.to_mesh_clear()
    return out


def state(obj):
    """What Possess must not touch when it fails, and what Release must give back."""
    return {"objects": sorted(o.name for o in bpy.data.objects), "actions": sorted(a.name for a in bpy.data.actions),
            "armatures": sorted(a.name for a in bpy.data.armatures), "meshes": sorted(m.name for m in bpy.data.meshes),
            "modifiers": [m.name for m in obj.modifiers], "groups": [g.name for g in obj.vertex_groups],
            "materials": [m.name for m in obj.data.materials], "keys": sorted(obj.keys())}


def report_of(operator):
    """The operator's result, or the report Blender turns into a RuntimeError for a script."""
    try:
        return {"result": sorted(operator()), "error": None}
    except RuntimeError as e:
        return {"result": None, "error": str(e)}


def main():
    job_path, out_path = sys.argv[sys.argv.index("--") + 1:][:2]
    with open(job_path) as f:
        job = json.load(f)
    out = {}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.preferences.addon_install(filepath=job["zip"], overwrite=True)
    bpy.ops.preferences.addon_enable(module="kinetre_blender")
    import kinetre_blender
    out["enabled"] = "kinetre_blender" in bpy.context.preferences.addons
    out["panel"] = hasattr(bpy.types, "KINETRE_PT_panel") and bpy.types.KINETRE_PT_panel.bl_category == "Kinetre"
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = job["fps"], 1.0
    bpy.ops.wm.obj_import(filepath=job["mesh"])
    obj = next(o for o in scene.objects if o.type == "MESH")
    obj.name = "Cow"
    material = bpy.data.materials.new("CowSkin")
    obj.data.materials.append(material)
    displace = obj.modifiers.new("Keep me", "DISPLACE")
    displace.strength = 0.0  # a modifier of the user's, which must stay (and here moves nothing)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    settings = scene.kinetre
    settings.target, settings.nodes = obj, job["nodes"]
    rest = world(obj)
    kinetre_blender.write_obj(obj, job["obj"])
    before = state(obj)

    settings.motion = job["broken"]
    out["broken"] = report_of(bpy.ops.kinetre.possess)
    out["broken_unchanged"] = state(obj) == before

    prefs = bpy.context.preferences.addons["kinetre_blender"].preferences
    prefs.command = "/nonexistent/bin/kinetre"
    settings.motion = job["motion"]
    out["missing"] = report_of(bpy.ops.kinetre.possess)
    out["missing_unchanged"] = state(obj) == before
    prefs.command = ""

    out["possess"] = report_of(bpy.ops.kinetre.possess)
    rig = bpy.data.objects.get(obj.get("kinetre_rig", ""))
    action = rig.animation_data.action if rig is not None and rig.animation_data else None
    out["after"] = state(obj)
    out["first_modifier"] = obj.modifiers[0].type if obj.modifiers else None
    out["rig_of_modifier"] = obj.modifiers[0].object.name if obj.modifiers and obj.modifiers[0].type == "ARMATURE" \
        else None
    out["rig"] = rig.name if rig else None
    out["bones"] = len(rig.data.bones) if rig else 0
    out["keys"] = sorted({len(fc.keyframe_points) for fc in action.fcurves}) if action else []
    out["frame_range"] = list(action.frame_range) if action else None
    out["frames"] = {}
    for frame in job["frames"]:
        scene.frame_set(frame)
        out["frames"][str(frame)] = world(obj).tolist()
    out["rest"] = rest.tolist()
    if job.get("shot"):
        shot(obj, rig, job["shot"], job["frames"][-1])

    out["release"] = report_of(bpy.ops.kinetre.release)
    scene.frame_set(job["frames"][-1])
    out["released"] = state(obj)
    out["released_moved"] = float(np.abs(world(obj) - rest).max())
    out["before"] = before
    with open(out_path, "w") as f:
        json.dump(out, f)


def shot(obj, rig, path, frame):
    """A small render of the possessed mesh at `frame`, a dot at each graph node's bone (Workbench, headless:
    the viewport's overlays, bones included, need a window)."""
    scene = bpy.context.scene
    scene.frame_set(frame)
    posed = world(obj)
    lo, hi = posed.min(axis=0), posed.max(axis=0)
    centre = (lo + hi) / 2 @ Y_UP  # back to Blender's axes
    size = float(np.max(hi - lo))
    nodes = set(obj.vertex_groups.keys())
    for bone in rig.pose.bones:
        if bone.name in nodes:
            bpy.ops.mesh.primitive_ico_sphere_add(radius=0.012 * size, subdivisions=2,
                                                  location=rig.matrix_world @ bone.head)
            bpy.context.active_object.color = (0.1, 0.35, 0.9, 1.0)
            bpy.context.active_object.show_in_front = True
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    from mathutils import Vector
    camera.rotation_euler = Vector((1.5, -1.7, 0.6)).to_track_quat("Z", "Y").to_euler()  # looking from there
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = 560, 360
    points = posed @ Y_UP  # Blender's axes
    location, _ = camera.camera_fit_coords(bpy.context.evaluated_depsgraph_get(), points.ravel().tolist())
    camera.location = Vector(location) + 0.25 * size * (Vector(location) - Vector(centre)).normalized()
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "STUDIO"
    scene.display.shading.color_type = "OBJECT"
    scene.display.shading.show_xray = True
    scene.display.shading.xray_alpha = 0.75
    obj.color = (0.85, 0.55, 0.35, 1.0)
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.compression = 100
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


main()
