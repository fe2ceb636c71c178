"""What a grid shows while it trains: runs done / running / queued, each running run's epoch and
ETA, the grid's ETA, workers lost and their runs re-queued.

The grid process learns it from the run folders alone, so that local worker processes and Dask
workers alike need to send nothing: a run is running while a live process holds its folder's
lock (``rnn_seg.runs.lock.appears_held``), and its epoch and time per epoch are the last row of
its ``history.csv``, which the run appends every epoch. A run's ETA is its epochs left times its
last time per epoch; the grid's is the wall time per epoch of the work done in this invocation
(runs finished and epochs of the running ones, parallelism included) times the work left, where
a run's work is its schedule's epochs (``weights``; runs differ: Pr 80 epochs, APoc 180 at the
converged preset; a resumed run counts only the epochs after its checkpoint).

On a terminal that can redraw lines the state is a live panel (``rich``) under the log lines,
each running run named by its configuration, seed and fold (``run_label``: ``APoc-gradnorm
seed0 B``, short enough for 80 columns); elsewhere (a file, a pipe, a batch job's log, a dumb
terminal: ``TERM=dumb``) it is a plain line every ``STATUS_EVERY`` seconds when it changed::

    [grid] 3/10 done, 2 running, 5 queued, ETA 0:12:00 | revised/bidirectional/A-fixed/seed0/B epoch 12/30 ETA 0:01:10; ...
"""
from __future__ import annotations

import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path
from typing import Callable, Iterator

from rnn_seg.runs.folder import HISTORY, is_finished
from rnn_seg.runs.lock import appears_held

from .job import error_text
from .spec import RunKey

Log = Callable[[str], None]

#: Seconds between two plain status lines (when something changed), and between two looks at
#: the run folders.
STATUS_EVERY, POLL_EVERY = 60.0, 2.0


@dataclass(frozen=True)
class RunningRun:
    """A run in training: ``epoch`` of ``epochs`` done (units of its schedule), the last one's
    seconds (None before its first epoch)."""

    key: RunKey
    epoch: float
    epochs: float
    unit_seconds: float | None

    @property
    def eta(self) -> timedelta | None:
        if self.unit_seconds is None:
            return None
        return timedelta(seconds=round(max(0.0, self.epochs - self.epoch) * self.unit_seconds))

    def describe(self) -> str:
        eta = "" if self.eta is None else f" ETA {self.eta}"
        return f"{self.key.path()} epoch {self.epoch:g}/{self.epochs:g}{eta}"


def run_label(key: RunKey) -> str:
    """A run's name in the live panel: its configuration (prefixed by its labels and direction
    where they are not the paper's, revised and bidirectional), seed and fold, e.g.
    ``APoc-gradnorm seed0 B``, ``original/forward/A-fixed seed1 C``."""
    prefix = "".join(f"{part}/" for part, default in ((key.annotations, "revised"),
                                                      (key.direction, "bidirectional"))
                     if part != default)
    return f"{prefix}{key.config_name} seed{key.seed} {key.fold}"


def last_epoch(run_dir: Path) -> tuple[float, float | None]:
    """``(units done, seconds of the last unit)`` from the last row of ``run_dir``'s
    ``history.csv``; ``(0, None)`` before its first row (or for a row cut short)."""
    try:
        with open(Path(run_dir) / HISTORY) as history:
            header = history.readline().strip().split(",")
            last = None
            for line in history:
                if line.endswith("\n"):
                    last = line
    except OSError:
        return 0.0, None
    if last is None:
        return 0.0, None
    row = dict(zip(header, last.strip().split(",")))
    try:
        return float(row["n"]), float(row["unit_seconds"])
    except (KeyError, ValueError):
        return 0.0, None


class Progress:
    """Counts runs and says how the grid gets on: one line per finished run, and the runs in
    training (``poll``: a live panel with ``live``, else a plain status line every
    ``status_every`` seconds when it changed).

    Args:
        total: the grid's runs.
        already: of those, finished before this invocation.
        log: where lines go.
        weights: the work each run to train has left, in epochs (the ETA's weights).
        clock: seconds, monotonic.
        after_job: called after every job that trained its runs to the end (e.g. to archive).
        out: the grid's folder, where the running runs are read; None = none are.
        epochs: each run's schedule, in epochs (default: its weight).
        after_run: called with the folder of each run trained to the end (e.g. MLflow).
        status_every: seconds between plain status lines.
        live: a ``rich.console.Console`` for a live panel; None = plain lines.
    """

    def __init__(self, total: int, already: int, log: Log, weights: dict[RunKey, float],
                 clock: Callable[[], float] = time.monotonic,
                 after_job: Callable[[], None] | None = None, *, out: Path | None = None,
                 epochs: dict[RunKey, float] | None = None,
                 after_run: Callable[[Path], None] | None = None,
                 status_every: float = STATUS_EVERY, live=None):
        self.total, self.done, self.log, self.clock = total, already, log, clock
        self.weights, self.started, self.after_job = weights, clock(), after_job
        self.work_left, self.work_done = float(sum(weights.values())), 0.0
        self.failed: list[tuple[RunKey, str]] = []
        self.out, self.after_run, self.status_every = out, after_run, status_every
        self.epochs = epochs or dict(weights)
        self.pending = set(weights)                  # to train: queued or running
        self.running: list[RunningRun] = []
        self._lock = threading.RLock()
        self._last_status: tuple[float, tuple] | None = None     # (time, state) of the last
        self._live = _LivePanel(live) if live is not None else None

    # -- runs ending ---------------------------------------------------------------------------
    def finished_group(self, keys: list[RunKey], error: BaseException | None = None) -> None:
        for key in keys:
            self.finished(key, error)
        if self.after_job and not error:
            self.after_job()

    def finished(self, key: RunKey, error: BaseException | None = None) -> None:
        with self._lock:
            self.done += 1
            self.pending.discard(key)
            self.running = [r for r in self.running if r.key != key]
            work = self.weights[key]
            self.work_done, self.work_left = self.work_done + work, max(0.0,
                                                                        self.work_left - work)
            if error:
                self.failed.append((key, error_text(error)))
            status = f"FAILED: {self.failed[-1][1]}" if error else "finished"
            self.log(f"[grid] {self.done}/{self.total} done, ETA {self._eta()} | "
                     f"{key.path()} {status}")
            self._show()
        if self.after_run and not error and self.out is not None:
            self.after_run(self.out / key.path())

    def worker_lost(self, worker: str, keys: list[RunKey], requeued: bool = True) -> None:
        """Say that ``worker`` ended while training ``keys``, re-queued (to resume from their
        checkpoints) unless ``requeued`` is False."""
        runs = ", ".join(str(k.path()) for k in keys) or "no run"
        self.log(f"[grid] worker lost: {worker}; "
                 + (f"re-queued (they resume from their last checkpoints): {runs}" if requeued
                    else f"its runs: {runs}"))

    # -- runs in training ----------------------------------------------------------------------
    def poll(self) -> None:
        """Read the running runs from their folders and show the state (see the class)."""
        if self.out is None:
            return
        running = []
        for key in sorted(self.pending, key=lambda k: str(k.path())):
            run_dir = self.out / key.path()
            if appears_held(run_dir) and not is_finished(run_dir):
                epoch, seconds = last_epoch(run_dir)
                running.append(RunningRun(key, epoch, self.epochs.get(key, 0.0), seconds))
        with self._lock:
            self.running = [r for r in running if r.key in self.pending]
            self._show()

    def status(self) -> str:
        """``3/10 done, 2 running, 5 queued, ETA 0:12:00`` (the runs known at the last poll)."""
        queued = len(self.pending) - len(self.running)
        return (f"{self.done}/{self.total} done, {len(self.running)} running, {queued} queued, "
                f"ETA {self._eta()}")

    def _show(self) -> None:
        """The live panel, or a plain status line when the runs in training moved on and the
        last line is ``status_every`` seconds old."""
        if self._live is not None:
            self._live.update(self.status(), self.running)
            return
        if not self.running:
            return
        state = (self.done, tuple((r.key, r.epoch) for r in self.running))
        now = self.clock()
        if self._last_status is not None and (state == self._last_status[1] or
                                              now - self._last_status[0] < self.status_every):
            return
        self._last_status = (now, state)
        self.log(f"[grid] {self.status()} | " + "; ".join(r.describe() for r in self.running))

    def _eta(self) -> timedelta | str:
        """The grid's ETA: wall time per epoch of the work done here times the work left."""
        partial = sum(min(self.weights[r.key],                      # epochs trained here
                          max(0.0, r.epoch - (r.epochs - self.weights[r.key])))
                      for r in self.running)
        done, left = self.work_done + partial, self.work_left - partial
        if not done:
            return "unknown"           # only runs with nothing left to train finished yet
        return timedelta(seconds=round((self.clock() - self.started) / done * max(0.0, left)))

    @contextmanager
    def watching(self, *checks: Callable[[], None], every: float = POLL_EVERY
                 ) -> Iterator[None]:
        """For the block: ``poll`` (and each of ``checks``, e.g. for lost workers) every
        ``every`` seconds in a thread, and the live panel on screen."""
        stop = threading.Event()

        def loop() -> None:
            while not stop.wait(every):
                for check in (self.poll, *checks):
                    try:
                        check()
                    except Exception as error:          # a display never stops the grid
                        self.log(f"[grid] warning: progress display: {error}")

        thread = threading.Thread(target=loop, name="grid-progress", daemon=True)
        if self._live is not None:
            self._live.start()
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()
            if self._live is not None:
                self._live.stop()


def live_console(console=None):
    """``console`` (default: ``rich``'s on standard output) where the live panel can be drawn:
    an interactive terminal, not a dumb one (``TERM=dumb`` cannot redraw lines, and the panel
    would never show); None elsewhere, for plain status lines."""
    from rich.console import Console

    console = console if console is not None else Console()
    return console if console.is_interactive else None


class _LivePanel:
    """The grid's state as a ``rich`` live panel: a status line and a bar per running run, kept
    under the log lines (which ``rich`` prints above it)."""

    def __init__(self, console):
        from rich.live import Live

        self.console = console
        self._live = Live(console=console, refresh_per_second=2, transient=True,
                          redirect_stdout=True, redirect_stderr=True)

    def start(self) -> None:
        self._live.start()

    def stop(self) -> None:
        self._live.stop()

    def update(self, status: str, running: list[RunningRun]) -> None:
        """The status line, then a row per running run: its name (never cut), a bar as wide as
        the terminal leaves room for, its epoch and ETA."""
        from rich.console import Group
        from rich.progress_bar import ProgressBar
        from rich.table import Table

        labels = [f"  {run_label(run.key)}" for run in running]
        bar = max(4, min(24, self.console.width - max(map(len, labels), default=0) - 30))
        table = Table.grid(padding=(0, 1))
        table.add_column(no_wrap=True)
        for label, run in zip(labels, running):
            table.add_row(label,
                          ProgressBar(total=max(run.epochs, 1), completed=run.epoch, width=bar),
                          f"epoch {run.epoch:g}/{run.epochs:g}",
                          "" if run.eta is None else f"ETA {run.eta}")
        self._live.update(Group(f"[bold]grid[/bold] {status}", table))
