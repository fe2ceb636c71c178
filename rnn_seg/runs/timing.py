"""Where a run's wall time goes: seconds per phase, saved next to its results as ``timing.json``.

Phases of a run: ``data`` (loading and preprocessing), ``trace`` (building the TensorFlow graphs
once), ``train`` (the training sweeps), ``monitor`` (progress lines), ``evaluate`` (evaluation
points: predictions, CSVs, plots) and ``checkpoint``. Process start and imports happen before a
run exists; ``bench/fold_time.py`` measures them from outside.

A run trained over several sessions (interrupted, then resumed) counts every session: each
checkpoint keeps the clock at that point (``rnn_seg.runs.checkpoints``) and a run resumed from it
continues that clock, so a finished run's ``timing.json`` holds the seconds that produced its
weights; work lost after the last checkpoint of an interrupted session is not counted, its redoing
is.
"""
from __future__ import annotations

import time
from collections import defaultdict
from contextlib import contextmanager
from typing import Iterator

PHASES = ("data", "trace", "train", "monitor", "evaluate", "checkpoint")


class PhaseClock:
    """Accumulates wall-clock seconds per named phase."""

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)

    @contextmanager
    def phase(self, name: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] += time.perf_counter() - start

    def add(self, name: str, seconds: float) -> None:
        self.seconds[name] += seconds

    def report(self) -> dict[str, float]:
        """Seconds of every phase (known ones first), rounded to milliseconds."""
        names = [p for p in PHASES if p in self.seconds] + sorted(set(self.seconds) - set(PHASES))
        return {name: round(self.seconds[name], 3) for name in names}
