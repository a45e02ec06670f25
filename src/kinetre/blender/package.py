"""`kinetre blender-addon -o kinetre_blender.zip`: the add-on (addon.py) as the zip Blender's Preferences
install, with the command that runs this Kinetre installation."""
from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path

from ..errors import ExportError

ADDON = Path(__file__).resolve().parent / "addon.py"
FOLDER = "kinetre_blender"  # the add-on's module name inside Blender


def addon_command() -> list[str]:
    """This installation's Kinetre, as the add-on runs it: its interpreter with `-m kinetre.cli`, which
    works for a pipx or a virtualenv install alike, whatever Blender's PATH holds."""
    return [sys.executable, "-m", "kinetre.cli"]


def write_addon(path, command: list[str] | None = None) -> Path:
    """Write the add-on zip to `path`; `command` (default `addon_command()`) is what Possess runs."""
    path = Path(path)
    if path.suffix.lower() != ".zip":
        raise ExportError(f"{path}: the add-on is a .zip (Blender installs it from Preferences > Add-ons)")
    config = {"command": command if command is not None else addon_command()}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr(f"{FOLDER}/__init__.py", ADDON.read_text())
            z.writestr(f"{FOLDER}/kinetre.json", json.dumps(config, indent=1) + "\n")
    except OSError as e:
        raise ExportError(f"{path}: cannot write the add-on ({e.strerror or e})") from None
    return path
