"""Wall and CPU seconds per stage of a run, for the summary line and the benchmarks."""
from __future__ import annotations

import time


class Stopwatch:
    """`lap(stage)` records `{stage}_s` (wall) and `{stage}_cpu` (CPU) seconds since the previous lap
    into `seconds`. CPU seconds are what a stage costs on a shared machine, where wall time also counts
    the other processes' turns."""

    def __init__(self, seconds: dict | None = None) -> None:
        self.seconds = {} if seconds is None else seconds
        self.restart()

    def restart(self) -> None:
        """Start the next lap now (time spent since the last lap is not counted)."""
        self._wall, self._cpu = time.perf_counter(), time.process_time()

    def lap(self, stage: str) -> None:
        wall, cpu = time.perf_counter(), time.process_time()
        self.seconds[f"{stage}_s"] = wall - self._wall
        self.seconds[f"{stage}_cpu"] = cpu - self._cpu
        self._wall, self._cpu = wall, cpu
