"""Face blendshapes → an avatar's morph target weights (its VRM expressions, else its ARKit-named targets),
and → VRM 1.0 expressions for a VRM Animation file (`vrm_expressions`).

MediaPipe's FaceLandmarker gives the 51 ARKit face-tracking weights (plus `_neutral`). An avatar takes them
through, in order:

1. VRM expressions (VRM 1.0 `VRMC_vrm.expressions`, VRM 0.x `VRM.blendShapeMaster.blendShapeGroups`): an
   expression named like a blendshape ("perfect sync" avatars) takes that weight; the presets take the
   blendshapes they stand for (`VRM_PRESETS`: aa ← jawOpen, ou ← mouthPucker, oh ← mouthFunnel,
   blinkLeft ← eyeBlinkLeft, happy ← the mean of both mouthSmiles, sad ← mouthFrowns, angry ← browDowns,
   surprised ← browInnerUp, ...; docs/vrm.md has the table); each expression then moves its bound morph
   targets by its bind weight.
2. Otherwise morph targets named after a blendshape (the glTF `extras.targetNames` three.js and Blender
   write, on the mesh or its first primitive), matched ignoring case, punctuation and a prefix
   ("jawOpen", "ARKit_JawOpen", "blendShape1.jawOpen").

Everything is linear, so the map is a matrix per mesh: weights = clip(W · blendshapes, 0, 1).

A VRM Animation carries expressions by name instead (`vrm_expressions`): each VRM 1.0 preset from the same
table, blink split so that blink + blinkLeft is the left eye's closure and blink + blinkRight the right
one's (a VRM player adds them), and every blendshape no preset uses as a custom expression of its own name.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..skeleton.mediapipe import BLENDSHAPE_TABLE
from .load import Avatar

# VRM 1.0 preset -> the blendshapes whose mean drives it (left and right are the face's own in both; lookLeft:
# both eyes turned to the face's left), and the VRM 0.x names of the same presets
VRM_PRESETS = {k: tuple(v) for k, v in BLENDSHAPE_TABLE["vrm_presets"].items()}
VRM0_NAMES = dict(BLENDSHAPE_TABLE["vrm0_names"])
# any spelling, lower case -> the blendshapes whose mean drives it
PRESETS = {**{k.lower(): v for k, v in VRM_PRESETS.items()},
           **{old: VRM_PRESETS[new] for old, new in VRM0_NAMES.items()}}
BLINKS = ("eyeBlinkLeft", "eyeBlinkRight")


@dataclass(frozen=True, eq=False)
class ExpressionMap:
    """matrices[mesh index] = (targets, B) weights from blendshapes to that mesh's morph targets;
    `names` the B blendshape names; `how` says which route was taken ("vrm" or "names")."""

    names: tuple[str, ...]
    matrices: dict
    how: str = ""

    def __bool__(self) -> bool:
        return any(np.any(m) for m in self.matrices.values())

    def weights(self, blendshapes: np.ndarray) -> dict:
        """mesh index -> (T, targets) morph weights for (T, B) blendshapes; a frame without a face (NaN)
        keeps the last frame's weights (zero before the first face)."""
        held = held_weights(blendshapes)
        return {mesh: np.clip(held @ m.T, 0.0, 1.0) for mesh, m in self.matrices.items() if np.any(m)}


def vrm_expressions(names, blendshapes: np.ndarray) -> tuple[dict, dict]:
    """(T, B) blendshape weights named `names` -> ({VRM 1.0 preset: (T,)}, {custom name: (T,)}) in [0, 1].

    A frame without a face (NaN) holds the last frame's weights (zero before the first face), as
    `ExpressionMap.weights` does. Presets none of whose blendshapes are in `names` are left out.
    """
    w = np.clip(held_weights(blendshapes), 0.0, 1.0)
    index = {n: i for i, n in enumerate(names)}
    preset = {}
    for name, sources in VRM_PRESETS.items():
        have = [index[s] for s in sources if s in index]
        if have and name not in ("blinkLeft", "blinkRight"):
            preset[name] = w[:, have].mean(axis=1)
    if all(b in index for b in BLINKS):
        left, right = w[:, index[BLINKS[0]]], w[:, index[BLINKS[1]]]
        both = np.minimum(left, right)
        preset.update(blink=both, blinkLeft=left - both, blinkRight=right - both)
    used = {s for sources in VRM_PRESETS.values() for s in sources}
    custom = {n: w[:, i] for n, i in index.items() if n not in used and not n.startswith("_")}
    return preset, custom


def held_weights(blendshapes) -> np.ndarray:
    """The weights, a frame with NaN holding the last finite frame (zeros before the first)."""
    b = np.asarray(blendshapes, dtype=np.float64)
    seen = np.isfinite(b).all(axis=1)
    last = np.maximum.accumulate(np.where(seen, np.arange(len(b)), -1))
    return np.where((last >= 0)[:, None], np.nan_to_num(b)[np.maximum(last, 0)], 0.0)


def _key(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", str(name).lower())


_PRESETS = {_key(k): v for k, v in PRESETS.items()}


def blendshapes_from_clips(clips: dict, names: tuple[str, ...]) -> np.ndarray | None:
    """Named expression weights as a VMC or VRM sender gives them -> (B,) weights for `names` in [0, 1], or None
    when no name is known.

    A name that is a blendshape's (any case: "jawOpen", "JawOpen") gives that weight; a preset (VRM 1.0 or 0.x:
    "aa", "A", "Joy", "Blink_L"...) gives its weight to each blendshape it stands for, unless that one came by
    name; "Blink" closes both eyes and adds to "Blink_L" / "Blink_R", the split `vrm_expressions` makes.
    """
    index = {_key(n): i for i, n in enumerate(names) if not n.startswith("_")}
    direct = np.full(len(names), np.nan)
    presets = np.zeros(len(names))
    known = False
    for name, weight in clips.items():
        k = _key(name)
        if k in index:
            direct[index[k]] = weight
            known = True
            continue
        sources = BLINKS if k == "blink" else _PRESETS.get(k, ())
        for source in sources:
            if _key(source) in index:
                presets[index[_key(source)]] += weight
                known = True
    if not known:
        return None
    return np.clip(np.where(np.isnan(direct), presets, direct), 0.0, 1.0)


def map_expressions(avatar: Avatar, names: tuple[str, ...]) -> ExpressionMap:
    """How `names` (the take's blendshapes) drive the avatar's morph targets (empty when nothing matches)."""
    doc = avatar.doc
    counts = {m: len((mesh.primitives[0].targets or []) if mesh.primitives else [])
              for m, mesh in enumerate(doc.meshes or [])}
    counts = {m: n for m, n in counts.items() if n}
    index = {_key(n): i for i, n in enumerate(names) if not n.startswith("_")}
    groups = _vrm_expressions(doc)
    if groups:
        per_left_right = any(_key(g) in ("blinkl", "blinkleft") for g, _ in groups)
        matrices = {m: np.zeros((n, len(names))) for m, n in counts.items()}
        for group, binds in groups:
            k = _key(group)
            drive = np.zeros(len(names))
            if k in index:
                drive[index[k]] = 1.0
            elif k in _PRESETS or (k == "blink" and not per_left_right):
                sources = _PRESETS.get(k, ("eyeBlinkLeft", "eyeBlinkRight"))
                used = [index[_key(s)] for s in sources if _key(s) in index]
                for i in used:
                    drive[i] += 1.0 / len(used)
            for mesh, target, weight in binds:
                if mesh in matrices and 0 <= target < counts[mesh]:
                    matrices[mesh][target] += weight * drive
        return ExpressionMap(tuple(names), matrices, "vrm")
    matrices = {}
    for m, n in counts.items():
        targets = _target_names(doc.meshes[m])
        w = np.zeros((n, len(names)))
        for t, target in enumerate(targets[:n]):
            k = _key(target)
            hit = [i for key, i in index.items() if k == key or k.endswith(key)]
            if hit:
                w[t, max(hit, key=lambda i: len(_key(names[i])))] = 1.0  # the longest name: "mouthSmileLeft"
        matrices[m] = w
    return ExpressionMap(tuple(names), matrices, "names")


def _target_names(mesh) -> list[str]:
    for holder in (mesh, mesh.primitives[0] if mesh.primitives else None):
        extras = getattr(holder, "extras", None)
        if isinstance(extras, dict) and isinstance(extras.get("targetNames"), list):
            return [str(n) for n in extras["targetNames"]]
    return []


def _vrm_expressions(doc) -> list[tuple[str, list[tuple[int, int, float]]]]:
    """[(expression name, [(mesh, morph target, weight 0..1), ...]), ...] from VRM 1.0 or 0.x."""
    ext = doc.extensions or {}
    out = []
    vrm1 = (ext.get("VRMC_vrm") or {}).get("expressions") if isinstance(ext.get("VRMC_vrm"), dict) else None
    if isinstance(vrm1, dict):
        for kind in ("preset", "custom"):
            for name, expr in (vrm1.get(kind) or {}).items():
                binds = []
                for b in (expr or {}).get("morphTargetBinds") or []:
                    node = b.get("node")
                    if isinstance(node, int) and 0 <= node < len(doc.nodes) and doc.nodes[node].mesh is not None:
                        binds.append((doc.nodes[node].mesh, int(b.get("index", -1)), float(b.get("weight", 1.0))))
                out.append((name, binds))
        return out
    vrm0 = ext.get("VRM") if isinstance(ext.get("VRM"), dict) else None
    for group in ((vrm0 or {}).get("blendShapeMaster") or {}).get("blendShapeGroups") or []:
        name = group.get("presetName") if group.get("presetName") not in (None, "", "unknown") else group.get("name")
        binds = [(int(b.get("mesh", -1)), int(b.get("index", -1)), float(b.get("weight", 100.0)) / 100.0)
                 for b in group.get("binds") or []]
        out.append((str(name or ""), binds))
    return out
