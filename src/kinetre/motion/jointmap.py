"""Joint maps: rename, drop and pair the joints of one or more sources into one skeleton (a small JSON file).

Two people driving the front and back legs of a horse (the paper's demo) are two takes joined into one
`Take` whose `SkeletonModel` holds the joints each map entry keeps, under their new names; a source's
root may hang under a joint of an earlier source (`"parent"`), so a bone joins the two people. The format
is documented in docs/joint-maps.md:

    {"sources": [
        {"keep": ["legs"], "rename": {"HipLeft": "FrontHipLeft"}, "offset": [0, 0, 0.5]},
        {"keep": ["legs"], "offset": [0, 0, -0.5]}
    ]}

One entry per `--motion`, in order (in the studio: per possessing user, in the order they possess).
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import BadMotionError, BadSkeletonError
from ..skeleton.models import SkeletonModel
from ..skeleton.subsets import subset_mask
from .fit import yaw_rotation
from .source import resample
from .take import Take

_KEYS = {"keep", "drop", "rename", "prefix", "offset", "yaw", "parent"}


@dataclass(frozen=True)
class SourceMap:
    """What one source contributes.

    Attributes
    ----------
    keep : tuple of str or None
        Joint names or subset names ("legs", "left arm", ...) kept; None keeps every joint.
    drop : tuple of str
        Joint or subset names left out (after `keep`).
    rename : dict
        Old joint name -> new name in the joined skeleton.
    prefix : str
        Put before the name of every kept joint `rename` does not name (two hands: "left_", "right_").
    offset : (3,) float64
        Added to every position of the source (its units: metres for people), after `yaw`.
    yaw : float
        Degrees about +Y the source is turned about its origin first.
    parent : dict
        New name of a joint of this source that is a root after dropping -> new name of a joint of an
        earlier source (or earlier in this one): a bone between the two.
    """

    keep: tuple[str, ...] | None = None
    drop: tuple[str, ...] = ()
    rename: dict = field(default_factory=dict)
    prefix: str = ""
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw: float = 0.0
    parent: dict = field(default_factory=dict)

    def mask(self, model: SkeletonModel, where: str = "joint map") -> np.ndarray:
        """(J,) bool: the joints of `model` this entry keeps."""
        try:
            keep = subset_mask(model, list(self.keep)) if self.keep is not None else np.ones(len(model.joints), bool)
            drop = subset_mask(model, list(self.drop)) if self.drop else np.zeros(len(model.joints), bool)
        except BadSkeletonError as e:
            raise BadMotionError(f"{where}: {e}") from None
        for old in self.rename:
            if old not in model.joints:
                raise BadMotionError(f"{where}: rename: {old!r} is not a joint of {model.name!r} "
                                     f"(joints: {', '.join(model.joints)})")
        return keep & ~drop

    def joint_names(self, model: SkeletonModel, where: str = "joint map") -> list[str]:
        """The (original) names of the joints of `model` this entry keeps: a subset for one studio user."""
        keep = self.mask(model, where)
        if not keep.any():
            raise BadMotionError(f"{where}: keeps no joint of {model.name!r}")
        return [n for n, k in zip(model.joints, keep) if k]


@dataclass(frozen=True)
class JointMap:
    """A parsed joint map: one `SourceMap` per source, and the file it came from."""

    sources: tuple[SourceMap, ...]
    path: str = "joint map"


def _names(value, key: str, where: str) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise BadMotionError(f"{where}: {key!r} must be a list of joint or subset names, got {value!r}")
    return tuple(value)


def _mapping(value, key: str, where: str) -> dict:
    if not isinstance(value, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in value.items()):
        raise BadMotionError(f"{where}: {key!r} must map joint names to joint names, got {value!r}")
    return dict(value)


def parse_joint_map(obj, where: str = "joint map") -> JointMap:
    """Check a decoded JSON object and return the `JointMap` (every key is checked, naming it on error)."""
    if not isinstance(obj, dict) or set(obj) != {"sources"} or not isinstance(obj["sources"], list) \
            or not obj["sources"]:
        raise BadMotionError(f"{where}: expected an object {{\"sources\": [ ... ]}} with one entry per source")
    out = []
    for i, entry in enumerate(obj["sources"]):
        at = f"{where}: sources[{i}]"
        if not isinstance(entry, dict):
            raise BadMotionError(f"{at} must be an object, got {entry!r}")
        unknown = set(entry) - _KEYS
        if unknown:
            raise BadMotionError(f"{at}: unknown key(s) {', '.join(sorted(unknown))} "
                                 f"(expected {', '.join(sorted(_KEYS))})")
        offset = entry.get("offset", [0.0, 0.0, 0.0])
        if not (isinstance(offset, list) and len(offset) == 3 and
                all(isinstance(v, (int, float)) and math.isfinite(v) for v in offset)):
            raise BadMotionError(f"{at}: 'offset' must be 3 finite numbers, got {offset!r}")
        yaw = entry.get("yaw", 0.0)
        if not (isinstance(yaw, (int, float)) and math.isfinite(yaw)):
            raise BadMotionError(f"{at}: 'yaw' must be a number of degrees, got {yaw!r}")
        rename = _mapping(entry.get("rename", {}), "rename", at)
        prefix = entry.get("prefix", "")
        if not isinstance(prefix, str):
            raise BadMotionError(f"{at}: 'prefix' must be a string, got {prefix!r}")
        if len(set(rename.values())) != len(rename):
            raise BadMotionError(f"{at}: 'rename' gives two joints the same new name")
        out.append(SourceMap(_names(entry["keep"], "keep", at) if "keep" in entry else None,
                             _names(entry.get("drop", []), "drop", at), rename, prefix,
                             np.array(offset, dtype=np.float64), float(yaw),
                             _mapping(entry.get("parent", {}), "parent", at)))
    return JointMap(tuple(out), where)


def read_joint_map(path: str | os.PathLike) -> JointMap:
    """Read a joint-map JSON file (see the module docstring and docs/joint-maps.md)."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as f:
            obj = json.load(f)
    except FileNotFoundError:
        raise BadMotionError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise BadMotionError(f"{path}: cannot read ({e})") from None
    except json.JSONDecodeError as e:
        raise BadMotionError(f"{path}: not valid JSON (line {e.lineno}: {e.msg})") from None
    return parse_joint_map(obj, path)


def join_takes(takes: list[Take], jmap: JointMap) -> Take:
    """The takes joined into one, as the map says: kept joints under their new names, each source turned
    and offset, a source's roots under the `parent` joints it names.

    Every take is resampled to the first one's frame rate; the joined take is as long as the shortest.
    When the map has more entries than takes, takes that record several people (camera takes) give one
    source per person, by increasing id: one camera's two people drive the two halves of a horse.

    Raises
    ------
    BadMotionError
        A different number of takes and map entries, an unknown joint or subset name, two kept joints with
        the same name, a `parent` entry that is not a root of its source or names no earlier joint, or
        nothing kept at all.
    """
    where = jmap.path
    if len(takes) < len(jmap.sources) and any(t.people for t in takes):
        takes = [one for t in takes for one in t.split_people()]
    if len(takes) != len(jmap.sources):
        raise BadMotionError(f"{where}: describes {len(jmap.sources)} source(s) but {len(takes)} motion(s) "
                             f"(people, for camera takes) were given")
    fps = takes[0].fps
    takes = [t if t.fps == fps else resample(t, fps) for t in takes]
    frames = min(len(t) for t in takes)
    names: list[str] = []
    parents: list[int] = []
    columns, tracked = [], []
    for i, (take, smap) in enumerate(zip(takes, jmap.sources)):
        at = f"{where}: sources[{i}] ({take.source or 'take'})"
        model = take.model
        keep = smap.mask(model, at)
        base = len(names)
        index = {}
        for j in np.flatnonzero(keep):
            new = smap.rename.get(model.joints[j], smap.prefix + model.joints[j])
            if new in names:
                raise BadMotionError(f"{at}: joint name {new!r} is kept twice; rename or drop one")
            p = model.parents[j]
            while p >= 0 and not keep[p]:
                p = model.parents[p]
            index[int(j)] = len(names)
            names.append(new)
            parents.append(index[p] if p >= 0 else -1)
        for child, target in smap.parent.items():
            if child not in names[base:]:
                raise BadMotionError(f"{at}: parent: {child!r} is not a joint this source keeps")
            k = names.index(child, base)
            if parents[k] != -1:
                raise BadMotionError(f"{at}: parent: {child!r} already has a parent; only a root can be hung")
            if target not in names[:k]:
                raise BadMotionError(f"{at}: parent: {target!r} names no joint of an earlier source")
            parents[k] = names.index(target)
        rot = yaw_rotation(smap.yaw)
        kept = np.flatnonzero(keep)
        columns.append(take.positions[:frames, kept] @ rot.T + smap.offset)
        tracked.append(take.tracked[:frames, kept])
    if not names:
        raise BadMotionError(f"{where}: keeps no joint of any source")
    stem = os.path.splitext(os.path.basename(where))[0]
    model = SkeletonModel(f"map:{stem}", tuple(names), tuple(parents))
    source = " + ".join(t.source or "take" for t in takes) + f" via {where}"
    return Take(model, np.concatenate(columns, axis=1), np.concatenate(tracked, axis=1), fps, source)
