"""Kinetre inside Blender (the add-on, addon.py, zipped by `kinetre blender-addon`) and through Blender (FBX
written by Blender's own exporter). Modules named `*_in_blender.py` and addon.py run in Blender's Python."""
