"""A mesh file's preprocessing kept between runs: the cleaned mesh, the up axis its shape stands on and its
deformation graph with skinning weights, found again by what the file holds (not its name or date) and the
settings that made them.

Loading and cleaning a mesh, sampling its graph and weighing every vertex cost more than the whole solve of
a short clip on a large mesh, and give the same arrays every time for the same file: `kinetre animate` keeps
them in the per-user cache folder (`userdirs.user_cache_dir()`, `meshes` in it), beside the compiled
kernels. An entry's name is a hash of

* the file's bytes,
* the code that made it: the sources of Kinetre's `mesh` and `graph` stages and of this module, and the
  versions of Python, numpy, numba and trimesh (a new version recomputes rather than trusting old arrays),
* for a graph, the settings: up axis, node count, seed; for the up axis found from the shape, the file's
  extension (glTF is +Y up by its specification).

Entries are numpy archives (no pickles), written to a temporary file and renamed, so a reader never sees
half an entry; an entry that cannot be read back whole is a miss and is written again. The folder is kept
under `LIMIT` bytes by deleting the entries used least recently. A mesh with a material (a texture image
object) is not kept: only arrays are.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from .graph.graph import DeformationGraph
from .mesh.mesh import Mesh
from .userdirs import user_cache_dir

__all__ = ["MeshCache", "LIMIT", "code_stamp"]

LIMIT = 2 << 30  # bytes of entries kept; a 386k-vertex mesh with its graph takes about 40 MB
PACKAGE = Path(__file__).resolve().parent
# the code whose output is kept: a change in any of it makes every entry stale
STAGES = ("mesh", "graph")
MODULES = ("preprocessed.py", "jit.py", "lazy.py")
DEPENDENCIES = ("numpy", "numba", "llvmlite", "trimesh")
# the arrays of an entry, and those that may be absent (None)
_MESH, _MESH_OPTIONAL = ("vertices", "faces", "normals", "uvs", "colors"), {"uvs", "colors"}
_GRAPH = ("nodes", "normals", "edges", "bridges", "vertex_nodes", "vertex_weights", "pieces", "radius")
_GRAPH_OPTIONAL = {"pieces"}


class MeshCache:
    """The kept preprocessing of one mesh file (see the module's docstring).

    `MeshCache.of_file(path)` hashes the file; `load_mesh()` returns its cleaned mesh (kept or loaded and
    kept); `graph(...)` and `upright(...)` a kept graph or up axis or None, `keep_graph` and `keep_upright`
    keep one.
    """

    def __init__(self, path: str, content: str, folder: Path | None = None):
        self.path = path
        self.folder = Path(folder) if folder is not None else user_cache_dir() / "meshes"
        self._stem = _digest(content, code_stamp())

    @classmethod
    def of_file(cls, path, folder: Path | None = None) -> MeshCache | None:
        """The cache of the file at `path`, or None when it cannot be read (the loader then says why)."""
        path = os.fspath(path)
        try:
            with open(path, "rb") as fh:
                content = hashlib.file_digest(fh, "blake2b").hexdigest()
        except OSError:
            return None
        return cls(path, content, folder)

    def load_mesh(self) -> Mesh:
        """The file's mesh as `kinetre.load_mesh` makes it, from the cache when kept there (with `source`
        this path); otherwise loaded and kept."""
        entry = self._entry("mesh")
        arrays = self._read(entry, _MESH, _MESH_OPTIONAL)
        if arrays is not None:
            return Mesh(**arrays, source=self.path)
        from .mesh.load import load_mesh
        mesh = load_mesh(self.path)
        if mesh.material is None:
            self._write(entry, {name: getattr(mesh, name) for name in _MESH})
        return mesh

    def graph(self, up: str, nodes: int, seed: int) -> DeformationGraph | None:
        """The kept graph (with skinning weights) of the mesh stood `up`, or None."""
        arrays = self._read(self._entry("graph", up, nodes, seed), _GRAPH, _GRAPH_OPTIONAL)
        if arrays is None:
            return None
        radius = float(arrays.pop("radius"))
        return DeformationGraph(**arrays, radius=radius)

    def keep_graph(self, graph: DeformationGraph, up: str, nodes: int, seed: int) -> None:
        """Keep `graph` (with its skinning weights) as the graph of the mesh stood `up` for these settings."""
        arrays = {name: np.asarray(getattr(graph, name)) for name in _GRAPH if getattr(graph, name) is not None}
        self._write(self._entry("graph", up, nodes, seed), arrays)

    def upright(self, source: str):
        """The kept `mesh.upright.Upright` found for the mesh read from a file named like `source` (its
        extension can say the up axis), or None."""
        arrays = self._read(self._entry("upright", _extensions(source)), ("upright",), set())
        if arrays is None:
            return None
        from .mesh.upright import Upright
        up, scores, reason = json.loads(str(arrays["upright"]))
        return Upright(up, scores, reason)

    def keep_upright(self, source: str, upright) -> None:
        """Keep `upright`, found for the mesh read from a file named like `source`."""
        text = json.dumps([upright.up, upright.scores, upright.reason])  # -inf scores as -Infinity
        self._write(self._entry("upright", _extensions(source)), {"upright": np.array(text)})

    def _entry(self, kind: str, *settings) -> Path:
        return self.folder / f"{_digest(self._stem, kind, *map(str, settings))}.{kind}.npz"

    def _read(self, entry: Path, names: tuple[str, ...], optional: set[str]) -> dict | None:
        """The entry's arrays (None for an absent optional one), or None when it is missing, unreadable or
        not whole."""
        try:
            with np.load(entry, allow_pickle=False) as archive:
                present = set(json.loads(str(archive["present"])))
                if entry.name != str(archive["name"]) or not present <= set(names) or \
                        not set(names) - optional <= present:
                    return None
                arrays = {name: archive[name] if name in present else None for name in names}
            os.utime(entry)  # used now: the last to be pruned
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
            return None
        return arrays

    def _write(self, entry: Path, arrays: dict) -> None:
        """Keep `arrays` (None values left out) as the entry; a folder that cannot be written is no error."""
        present = [name for name, value in arrays.items() if value is not None]
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            fd, temporary = tempfile.mkstemp(dir=self.folder, prefix=".writing-", suffix=".npz")
            try:
                with os.fdopen(fd, "wb") as fh:
                    np.savez(fh, name=np.array(entry.name), present=np.array(json.dumps(present)),
                             **{name: arrays[name] for name in present})
                os.replace(temporary, entry)
            except BaseException:
                os.unlink(temporary)
                raise
            prune(self.folder, LIMIT)
        except OSError:
            pass


def prune(folder: Path, limit: int) -> None:
    """Delete the least recently used entries of `folder` until the rest take at most `limit` bytes."""
    entries = []
    for item in os.scandir(folder):
        if item.name.endswith(".npz") and not item.name.startswith(".writing-"):
            try:
                stat = item.stat()
            except OSError:
                continue
            entries.append((stat.st_mtime, stat.st_size, item.path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= limit:
            break
        try:
            os.unlink(path)
        except OSError:
            continue
        total -= size


def code_stamp(package: Path = PACKAGE) -> str:
    """Hash of the code whose output is kept (`STAGES`, `MODULES`) and of `DEPENDENCIES`' versions."""
    digest = hashlib.blake2b(digest_size=16)
    files = [package / name for name in MODULES]
    for stage in STAGES:
        files += sorted((package / stage).glob("*.py"))
    for file in files:
        digest.update(file.relative_to(package).as_posix().encode() + b"\0" + file.read_bytes() + b"\0")
    digest.update(repr((sys.version_info[:3], _versions(DEPENDENCIES))).encode())
    return digest.hexdigest()


def _versions(names) -> dict[str, str]:
    """Installed versions of `names`, read from their distribution folders' names (importing them, or
    importlib.metadata, would cost a tenth of a second)."""
    wanted = {name.lower(): name for name in names}
    found: dict[str, str] = {}
    for place in sys.path:
        try:
            listing = os.listdir(place or ".")
        except OSError:
            continue
        for item in listing:
            if item.endswith((".dist-info", ".egg-info")):
                name, _, version = item.rsplit(".", 1)[0].partition("-")
                key = name.lower().replace("_", "-")
                if key in wanted and wanted[key] not in found:
                    found[wanted[key]] = version
    return found


def _extensions(path: str) -> str:
    """".ply", ".ply.gz", ".glb": the lower-cased extensions of a file name."""
    return "".join(Path(path).suffixes).lower()


def _digest(*parts: str) -> str:
    return hashlib.blake2b("\0".join(parts).encode(), digest_size=16).hexdigest()
