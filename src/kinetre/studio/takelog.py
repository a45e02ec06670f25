"""A take being recorded, appended to a JSON-lines file and flushed frame by frame.

The scene writes each solved frame here *before* publishing it, so every frame a viewer saw is on disk
even if the scene process is killed mid-take; `read_take_log` turns the file back into `TakeFrame`s
(what the studio exports as GLB/BVH when the take stops).

One line per frame: {"seq": scene frame number, "t": ms, "x": base64 float64 (N, 12) = R row-major | t,
"energy": E, "iterations": k, "skeletons": {client: {"model": name, "positions": base64 float64 (J, 3),
"tracked": [bool], "hands": base64 float64 (2, 21, 3) and "blendshapes": base64 float64 (52,) when the user
sent them}}}.
"""
from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np

from ..deform.pose import GraphPose
from ..errors import KinetreError
from ..skeleton.models import MODELS, Skeleton


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a, "<f8").tobytes()).decode()


def _array(text: str, shape) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), "<f8").reshape(shape).copy()


class TakeLog:
    """Append-only, flushed per frame; `frames` counts what reached the file."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "w", encoding="utf-8")
        self.frames = 0

    def append(self, seq: int, t: float, pose: GraphPose, skeletons: dict[str, Skeleton],
               hands: dict[str, np.ndarray] | None = None, blendshapes: dict[str, np.ndarray] | None = None) -> None:
        """One solved frame; `hands` and `blendshapes` by client, for the clients that sent them."""
        x = np.concatenate([pose.rotations.reshape(-1, 9), pose.translations], axis=1)
        records = {}
        for c, s in skeletons.items():
            if s is None:
                continue
            records[c] = {"model": s.model.name, "positions": _b64(s.positions), "tracked": s.tracked.tolist()}
            for key, values in (("hands", hands), ("blendshapes", blendshapes)):
                if values and values.get(c) is not None:
                    records[c][key] = _b64(values[c])
        line = {"seq": seq, "t": t, "x": _b64(x), "energy": None if not np.isfinite(pose.energy) else pose.energy,
                "iterations": int(pose.iterations), "skeletons": records}
        self._file.write(json.dumps(line) + "\n")
        self._file.flush()  # in the OS's hands: survives a kill -9 of this process
        self.frames += 1

    def close(self) -> None:
        self._file.close()


def read_take_log(path: str | Path) -> list[tuple[int, float, GraphPose, dict, dict, dict]]:
    """(seq, t, pose, skeletons, hands, blendshapes) per frame, the last three by client (hands (2, 21, 3) and
    blendshapes (52,) only for clients that sent them); a torn last line (the writer was killed mid-write) is
    skipped."""
    out = []
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    for number, text in enumerate(lines, 1):
        try:
            rec = json.loads(text)
        except ValueError:
            if number == len(lines):
                break
            raise KinetreError(f"{path}: line {number} is not JSON") from None
        x = _array(rec["x"], (-1, 12))
        pose = GraphPose(x[:, :9].reshape(-1, 3, 3), x[:, 9:].copy(),
                         float("nan") if rec["energy"] is None else rec["energy"], rec["iterations"])
        skeletons, hands, blendshapes = {}, {}, {}
        for client, s in rec["skeletons"].items():
            model = MODELS[s["model"]]
            skeletons[client] = Skeleton(model, _array(s["positions"], (len(model.joints), 3)),
                                         np.asarray(s["tracked"], bool))
            if "hands" in s:
                hands[client] = _array(s["hands"], (2, 21, 3))
            if "blendshapes" in s:
                blendshapes[client] = _array(s["blendshapes"], (-1,))
        out.append((rec["seq"], rec["t"], pose, skeletons, hands, blendshapes))
    return out
