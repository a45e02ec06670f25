"""The Kinetre add-on for Blender 3.4+ (runs inside Blender; `kinetre blender-addon` zips it with the command
that runs the installed Kinetre).

View3D > Sidebar > Kinetre: a mesh object, a motion (BVH, glTF/GLB with `#animation`, take, video), a node
count and a subset; **Possess** writes the object as it stands in the scene (world coordinates, +Y up) to a
temporary OBJ, runs `kinetre animate … --up y --fps SCENE_FPS --exact-joints --progress` in a subprocess
(its progress in the status bar), imports the rigged glTF it writes with Blender's own importer and moves
the rig onto the object: the armature (graph nodes as bones) and its action stay, the object gets the
weights as vertex groups and an Armature modifier first in its stack; its mesh, materials and other
modifiers are untouched. **Release** removes all of that again. Kinetre's one-line errors (no Kinetre, a bad
file, a refused mesh) land in the report area; the scene is changed only once the take is back.
"""
import json
import os
import re
import shutil
import subprocess
import tempfile
import threading

import bpy
from bpy.props import IntProperty, PointerProperty, StringProperty

bl_info = {
    "name": "Kinetre",
    "author": "The Kinetre authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > Kinetre",
    "description": "Possess any mesh with a motion clip or a video: no rigging (embedded deformation)",
    "category": "Animation",
}

_CONFIG = os.path.join(os.path.dirname(os.path.abspath(__file__)), "kinetre.json")
_PROGRESS = re.compile(r"^kinetre: progress: (\w+) (\d+)/(\d+)$")
_MODIFIER = "Kinetre"
_JOBS = {}  # object name -> running job (the modal operator's)


class KinetreFailure(Exception):
    """A one-line message for the report area."""


def kinetre_command(context):
    """The command that runs Kinetre: the preference if set, else the one the add-on was written by, else
    `kinetre` on PATH."""
    prefs = context.preferences.addons[__package__ or __name__].preferences
    if prefs.command.strip():
        path = bpy.path.abspath(prefs.command.strip())
        if not (os.path.isfile(path) and os.access(path, os.X_OK)):
            raise KinetreFailure(f"Kinetre: {path}: no such program (the add-on's preferences name it)")
        return [path]
    try:
        with open(_CONFIG) as fh:
            command = json.load(fh)["command"]
        if command and os.path.isfile(command[0]) and os.access(command[0], os.X_OK):
            return list(command)
    except (OSError, ValueError, KeyError):
        pass
    found = shutil.which("kinetre")
    if found:
        return [found]
    raise KinetreFailure("Kinetre is not installed: `pipx install kinetre`, or name its `kinetre` program in "
                         "the add-on's preferences")


def write_obj(obj, path):
    """The object's evaluated-free mesh in world coordinates, +Y up (Blender is +Z up), as triangles."""
    mesh = obj.data
    mesh.calc_loop_triangles()
    m = obj.matrix_world
    with open(path, "w") as fh:
        for v in mesh.vertices:
            x, y, z = m @ v.co
            fh.write(f"v {x:.9g} {z:.9g} {-y:.9g}\n")
        for t in mesh.loop_triangles:
            a, b, c = t.vertices
            fh.write(f"f {a + 1} {b + 1} {c + 1}\n")


class Job:
    """One `kinetre animate` run: its process, the stderr lines read so far, its files."""

    def __init__(self, context, obj, settings):
        motion = settings.motion.strip()
        if not motion:
            raise KinetreFailure("Kinetre: choose a motion file (BVH, glTF/GLB#animation, take or video)")
        file_part = bpy.path.abspath(motion.split("#", 1)[0])
        motion = file_part + ("#" + motion.split("#", 1)[1] if "#" in motion else "")
        if not os.path.exists(file_part):
            raise KinetreFailure(f"Kinetre: {file_part}: no such motion file")
        if obj is None or obj.type != "MESH":
            raise KinetreFailure("Kinetre: choose a mesh object to possess")
        if obj.get("kinetre_rig"):
            raise KinetreFailure(f"Kinetre: {obj.name} is possessed already: Release it first")
        if len(obj.data.polygons) == 0:
            raise KinetreFailure(f"Kinetre: {obj.name} has no faces to possess")
        command = kinetre_command(context)
        scene = context.scene
        self.fps = scene.render.fps / scene.render.fps_base
        self.obj_name, self.motion = obj.name, motion
        self.folder = tempfile.mkdtemp(prefix="kinetre-")
        self.mesh_path = os.path.join(self.folder, "mesh.obj")
        self.take_path = os.path.join(self.folder, "take.glb")
        write_obj(obj, self.mesh_path)
        argv = command + ["animate", self.mesh_path, "--motion", motion, "-o", self.take_path,
                          "--nodes", str(settings.nodes), "--up", "y", "--fps", f"{self.fps:g}",
                          "--exact-joints", "--progress"]
        if settings.subset.strip():
            argv += ["--subset", settings.subset.strip()]
        self.lines, self.stage, self.done, self.total = [], "starting", 0, 0
        try:
            self.process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                            stderr=subprocess.PIPE, text=True, errors="replace")
        except OSError as e:
            self.cleanup()
            raise KinetreFailure(f"Kinetre: cannot run {argv[0]}: {e.strerror or e}") from None
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.process.stderr:
            line = line.rstrip("\n")
            found = _PROGRESS.match(line)
            if found:
                self.stage, self.done, self.total = found[1], int(found[2]), int(found[3])
            elif line.strip():
                self.lines.append(line)

    def status(self):
        return f"Kinetre: {self.stage} {self.done}/{self.total}" if self.total else f"Kinetre: {self.stage}"

    def wait(self, progress=None):
        """Block until the run ends (a script or background Blender: no event loop to poll from)."""
        while self.process.poll() is None:
            self.reader.join(0.2)
            if progress is not None:
                progress(self)
        self.reader.join()

    def result(self):
        """The glTF path, or KinetreFailure with Kinetre's own one-line error."""
        if self.process.returncode != 0 or not os.path.isfile(self.take_path):
            errors = [ln for ln in self.lines if ln.startswith("kinetre: error:")]
            message = (errors or self.lines or [f"kinetre exited with status {self.process.returncode}"])[-1]
            raise KinetreFailure(message.replace(self.mesh_path, self.obj_name))
        return self.take_path

    def cancel(self):
        if self.process.poll() is None:
            self.process.terminate()
            self.process.wait()
        self.cleanup()

    def cleanup(self):
        shutil.rmtree(self.folder, ignore_errors=True)


def _numpy_for_old_importers():
    import numpy
    if not hasattr(numpy, "bool"):  # Blender 3.4's glTF importer calls np.bool, which numpy 1.24 removed
        numpy.bool = bool


def bring_back(context, job):
    """Import the take and move its rig onto the job's object; returns a summary line."""
    from mathutils.kdtree import KDTree
    obj = bpy.data.objects.get(job.obj_name)
    if obj is None:
        raise KinetreFailure(f"Kinetre: {job.obj_name} was deleted while Kinetre ran")
    _numpy_for_old_importers()
    before = set(bpy.data.objects)
    selected = [o for o in context.view_layer.objects if o.select_get()]
    active = context.view_layer.objects.active
    bpy.ops.import_scene.gltf(filepath=job.take_path)
    new = [o for o in bpy.data.objects if o not in before]
    rig = next((o for o in new if o.type == "ARMATURE"), None)
    carrier = next((o for o in new if o.type == "MESH"), None)
    try:
        if rig is None or carrier is None:
            raise KinetreFailure(f"Kinetre: {job.take_path}: no rigged mesh in Kinetre's output")
        # Kinetre's mesh is the object's own vertices, maybe merged where they coincide: match by position
        carried = [carrier.matrix_world @ v.co for v in carrier.data.vertices]
        tree = KDTree(len(carried))
        for i, co in enumerate(carried):
            tree.insert(co, i)
        tree.balance()
        names = [g.name for g in carrier.vertex_groups]
        weights = [[(names[g.group], g.weight) for g in v.groups] for v in carrier.data.vertices]
        groups = {}
        for name in names:
            groups[name] = obj.vertex_groups.new(name=name)
        world = obj.matrix_world
        for v in obj.data.vertices:
            _, nearest, _ = tree.find(world @ v.co)
            for name, w in weights[nearest]:
                groups[name].add([v.index], w, "REPLACE")
        modifier = obj.modifiers.new(_MODIFIER, "ARMATURE")
        modifier.object = rig
        while obj.modifiers.find(_MODIFIER) > 0:  # first in the stack: it deforms the mesh the others see
            with context.temp_override(object=obj, active_object=obj):
                bpy.ops.object.modifier_move_up(modifier=_MODIFIER)
    except Exception:
        for o in new:
            bpy.data.objects.remove(o, do_unlink=True)
        raise
    mesh_data = carrier.data
    bpy.data.objects.remove(carrier, do_unlink=True)
    bpy.data.meshes.remove(mesh_data)
    for o in new:
        if o not in (carrier, rig):
            bpy.data.objects.remove(o, do_unlink=True)
    rig.name = rig.data.name = f"{obj.name} Kinetre rig"
    action = rig.animation_data.action if rig.animation_data else None
    if action is not None:
        action.name = f"{obj.name} Kinetre"
    obj["kinetre_rig"] = rig.name
    obj["kinetre_groups"] = names
    obj["kinetre_motion"] = job.motion
    for o in context.view_layer.objects:
        o.select_set(o in selected)
    context.view_layer.objects.active = active
    frames = int(round(action.frame_range[1] - action.frame_range[0])) + 1 if action is not None else 0
    if action is not None:
        context.scene.frame_start, context.scene.frame_end = int(action.frame_range[0]), int(action.frame_range[1])
    return f"Kinetre: {obj.name} possessed by {os.path.basename(job.motion)}: {frames} frames, {len(names)} bones"


def release(obj):
    """Undo `bring_back`: the modifier, the vertex groups, the rig and its action go; the mesh stays."""
    rig = bpy.data.objects.get(obj.get("kinetre_rig", ""))
    modifier = obj.modifiers.get(_MODIFIER)
    if modifier is not None:
        obj.modifiers.remove(modifier)
    for name in obj.get("kinetre_groups", []):
        group = obj.vertex_groups.get(name)
        if group is not None:
            obj.vertex_groups.remove(group)
    if rig is not None:
        action = rig.animation_data.action if rig.animation_data else None
        armature = rig.data
        bpy.data.objects.remove(rig, do_unlink=True)
        if armature is not None and armature.users == 0:
            bpy.data.armatures.remove(armature)
        if action is not None and action.users == 0:
            bpy.data.actions.remove(action)
    for key in ("kinetre_rig", "kinetre_groups", "kinetre_motion"):
        if key in obj:
            del obj[key]


class KinetreSettings(bpy.types.PropertyGroup):
    target: PointerProperty(name="Mesh", type=bpy.types.Object, poll=lambda self, o: o.type == "MESH",
                            description="The mesh object to possess (default: the active object)")
    motion: StringProperty(name="Motion", subtype="FILE_PATH",
                           description="BVH, glTF/GLB (file.glb#animation), .kinetre.jsonl take, or a video")
    nodes: IntProperty(name="Nodes", default=256, min=2, max=8192, description="Deformation graph nodes")
    subset: StringProperty(name="Subset", default="",
                           description='Joints that drive, e.g. "right arm" or "HipCenter,right arm" (empty: all)')


def _target(context):
    settings = context.scene.kinetre
    return settings.target or context.active_object


class KINETRE_OT_possess(bpy.types.Operator):
    """Run Kinetre on the mesh with the motion and bring the take back as an armature and an action"""
    bl_idname = "kinetre.possess"
    bl_label = "Possess"
    bl_options = {"REGISTER", "UNDO"}

    _timer = None
    _job = None

    def _start(self, context):
        try:
            return Job(context, _target(context), context.scene.kinetre)
        except KinetreFailure as e:
            self.report({"ERROR"}, str(e))
            return None

    def _finish(self, context, job):
        try:
            job.result()
            self.report({"INFO"}, bring_back(context, job))
            return {"FINISHED"}
        except KinetreFailure as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        except Exception as e:  # an importer's failure: one line, never a traceback in the report
            self.report({"ERROR"}, f"Kinetre: cannot bring the take back: {' '.join(str(e).split())}")
            return {"CANCELLED"}
        finally:
            job.cleanup()

    def execute(self, context):  # scripts and background Blender: wait for the run
        job = self._start(context)
        if job is None:
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            job.wait(lambda j: wm.progress_update(100 * j.done // max(j.total, 1)))
        finally:
            wm.progress_end()
        return self._finish(context, job)

    def invoke(self, context, event):  # the UI: poll the run from a timer, progress in the status bar
        job = self._start(context)
        if job is None:
            return {"CANCELLED"}
        self._job = job
        _JOBS[job.obj_name] = job
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.2, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC":
            job.cancel()
            self._end(context)
            self.report({"WARNING"}, "Kinetre: cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if job.process.poll() is None:
            context.workspace.status_text_set(job.status() + "  (Esc cancels)")
            context.window_manager.progress_update(100 * job.done // max(job.total, 1))
            return {"PASS_THROUGH"}
        job.reader.join()
        self._end(context)
        return self._finish(context, job)

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)
        _JOBS.pop(self._job.obj_name, None)


class KINETRE_OT_release(bpy.types.Operator):
    """Remove Kinetre's armature, action, weights and modifier from the mesh"""
    bl_idname = "kinetre.release"
    bl_label = "Release"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _target(context)
        if obj is None or not obj.get("kinetre_rig"):
            self.report({"ERROR"}, "Kinetre: the mesh is not possessed")
            return {"CANCELLED"}
        release(obj)
        self.report({"INFO"}, f"Kinetre: {obj.name} released")
        return {"FINISHED"}


class KINETRE_PT_panel(bpy.types.Panel):
    bl_label = "Kinetre"
    bl_idname = "KINETRE_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Kinetre"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.kinetre
        layout.prop(settings, "target")
        layout.prop(settings, "motion")
        row = layout.row()
        row.prop(settings, "nodes")
        layout.prop(settings, "subset")
        obj = _target(context)
        job = _JOBS.get(obj.name) if obj is not None else None
        if job is not None:
            layout.label(text=job.status())
        elif obj is not None and obj.get("kinetre_rig"):
            layout.label(text=f"{obj.name}: {os.path.basename(obj.get('kinetre_motion', ''))}")
            layout.operator("kinetre.release", icon="X")
        else:
            layout.operator("kinetre.possess", icon="ARMATURE_DATA")


class KinetrePreferences(bpy.types.AddonPreferences):
    bl_idname = __package__ or __name__

    command: StringProperty(name="kinetre program", subtype="FILE_PATH", default="",
                            description="The `kinetre` program to run (empty: the one that wrote this add-on, "
                                        "else `kinetre` on PATH)")

    def draw(self, context):
        self.layout.prop(self, "command")


_CLASSES = (KinetreSettings, KinetrePreferences, KINETRE_OT_possess, KINETRE_OT_release, KINETRE_PT_panel)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.kinetre = PointerProperty(type=KinetreSettings)


def unregister():
    del bpy.types.Scene.kinetre
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
