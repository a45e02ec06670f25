"""`kinetre blender-addon -o kinetre_blender.zip`: the Blender add-on that possesses a mesh from inside Blender."""
from __future__ import annotations


def register(sub) -> None:
    """Add `kinetre blender-addon` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("blender-addon", help="write the Kinetre add-on for Blender 3.4+ (docs/blender.md)")
    p.add_argument("-o", "--output", default="kinetre_blender.zip", help="the add-on zip (default kinetre_blender.zip)")
    p.set_defaults(func=cmd_blender_addon)


def cmd_blender_addon(args) -> int:
    from ..blender.package import addon_command, write_addon
    path = write_addon(args.output)
    print(f"wrote {path}: install it in Blender (Edit > Preferences > Add-ons > Install), enable \"Kinetre\"; "
          f"Possess runs {' '.join(addon_command())}")
    return 0
