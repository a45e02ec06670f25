"""Takes: every mesh's solved frames while the scene records, each mesh's in a take log of its own.

A take log is appended to a JSON-lines file and flushed frame by frame. The scene writes each solved frame
here *before* publishing it, so every frame a viewer saw is on disk even if the scene process is killed
mid-take; `read_take_log` turns the file back into `TakeFrame`s (what the studio exports as GLB/BVH when the
take stops, recording.py).

One line per frame: {"seq": scene frame number, "t": ms, "x": base64 float64 (N, 12) = R row-major | t,
"energy": E, "iterations": k, "skeletons": {client: {"model": name, "positions": base64 float64 (J, 3),
"tracked": [bool], "hands": base64 float64 (2, 21, 3) and "blendshapes": base64 float64 (52,) when the user
sent them}}}.
"""
from __future__ import annotations

import base64
import json
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...deform.pose import GraphPose
from ...errors import KinetreError
from ...skeleton.models import MODELS, Skeleton


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a, "<f8").tobytes()).decode()


def _array(text: str, shape) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), "<f8").reshape(shape).copy()


@dataclass
class TakeFrame:
    """One solved frame of a take: the pose and, per possessing user, the skeleton, hands and blendshapes it
    was solved from (hands and blendshapes only for users who sent them)."""

    t: float
    pose: GraphPose
    skeletons: dict[str, Skeleton] = field(default_factory=dict)
    hands: dict[str, np.ndarray] = field(default_factory=dict)
    blendshapes: dict[str, np.ndarray] = field(default_factory=dict)


def resample(take: list[TakeFrame], fps: float) -> list[TakeFrame]:
    """The take at a fixed rate: frame k is the newest solved frame at time t0 + k / fps (held, not blended)."""
    if not take:
        return []
    times = np.array([f.t for f in take])
    count = int((times[-1] - times[0]) / 1000.0 * fps) + 1
    picks = np.searchsorted(times, times[0] + np.arange(count) * 1000.0 / fps, side="right") - 1
    return [take[i] for i in picks]


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


class Recording:
    """The folder of the take being recorded (None while nothing records) and each mesh's take log in it."""

    def __init__(self):
        self.folder: Path | None = None
        self.logs: dict[int, TakeLog] = {}  # by mesh id

    @property
    def on(self) -> bool:
        return self.folder is not None

    def start(self, mesh_ids: list[int], folder: str | Path | None = None) -> Path:
        """Record into `folder` (a temporary folder by default) a take log for each of `mesh_ids`."""
        self.close()
        self.folder = Path(tempfile.mkdtemp(prefix="kinetre-recording-")) if folder is None else Path(folder)
        for mesh_id in mesh_ids:
            self.add(mesh_id)
        return self.folder

    def add(self, mesh_id: int) -> TakeLog | None:
        """A take log for mesh `mesh_id` while recording (None otherwise): take-mesh<id>.log.jsonl, what is
        left on disk if the scene is killed."""
        if self.folder is None:
            return None
        self.logs[mesh_id] = TakeLog(self.folder / f"take-mesh{mesh_id}.log.jsonl")
        return self.logs[mesh_id]

    def drop(self, mesh_id: int) -> None:
        """Mesh `mesh_id` left the scene: its log is closed (its frames so far stay on disk)."""
        log = self.logs.pop(mesh_id, None)
        if log is not None:
            log.close()

    def close(self) -> dict[int, Path]:
        """Close every log; their paths by mesh id."""
        paths = {i: log.path for i, log in self.logs.items()}
        for log in self.logs.values():
            log.close()
        self.logs = {}
        return paths

    def stop(self) -> dict[int, list[TakeFrame]]:
        """Each mesh's recorded frames by mesh id, read back from the take logs (which are then removed, with
        the folder when it is ours: a caller's is left alone)."""
        folder, self.folder = self.folder, None
        takes = {i: [TakeFrame(*frame[1:]) for frame in read_take_log(path)] for i, path in self.close().items()}
        if folder is not None and folder.name.startswith("kinetre-recording-"):
            shutil.rmtree(folder, ignore_errors=True)
        return takes
