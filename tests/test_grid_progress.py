"""What a grid shows while it trains, read from its run folders: runs done / running / queued,
each running run's epoch and ETA, the grid's ETA (plain lines off a terminal, a live panel on
one), and a worker lost with its runs re-queued (local processes and Dask)."""
from __future__ import annotations

import io
import os
import re
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from multitask.grid import executors
from multitask.grid.progress import Progress, last_epoch, live_console, run_label
from multitask.grid.spec import RunKey

KEYS = [RunKey("revised", "bidirectional", "A", "fixed", 0, fold) for fold in "BCDE"]


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _training(out: Path, key: RunKey, epochs: int, seconds: float = 2.0,
              pid: int | None = None) -> Path:
    """A run folder as a run in training leaves it: its lock and ``epochs`` history rows."""
    run = out / key.path()
    run.mkdir(parents=True, exist_ok=True)
    (run / ".lock").write_text(f"{pid or os.getpid()} {socket.gethostname()} 2026-11-27T10:00\n")
    rows = "".join(f"epochs,{n},{7 * n},1.0,0.5,{seconds},{n * seconds}\n"
                   for n in range(1, epochs + 1))
    (run / "history.csv").write_text("unit,n,sweep,lr,loss_gesture,unit_seconds,"
                                     f"elapsed_seconds\n{rows}")
    return run


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_plain_status_names_the_running_runs_their_epochs_and_etas(tmp_path):
    clock, lines = Clock(), []
    _training(tmp_path, KEYS[0], epochs=3)
    _training(tmp_path, KEYS[1], epochs=5, pid=_dead_pid())     # its process died: not running
    progress = Progress(5, 1, lines.append, {k: 10.0 for k in KEYS}, clock=clock, out=tmp_path,
                        status_every=60)
    clock.now = 30.0
    progress.poll()
    assert lines == [f"[grid] 1/5 done, 1 running, 3 queued, ETA 0:06:10 | {KEYS[0].path()} "
                     "epoch 3/10 ETA 0:00:14"]      # 30 s for 3 epochs, 37 of 40 left; 7 x 2 s
    clock.now = 200.0
    progress.poll()                                   # nothing moved on: no line
    _training(tmp_path, KEYS[0], epochs=4)
    clock.now = 220.0
    progress.poll()
    assert len(lines) == 2 and "epoch 4/10 ETA 0:00:12" in lines[1]
    _training(tmp_path, KEYS[0], epochs=5)
    clock.now = 240.0
    progress.poll()                                   # moved on, but the last line is fresh
    assert len(lines) == 2
    progress.finished(KEYS[0])
    assert lines[-1].startswith("[grid] 2/5 done, ETA ") and lines[-1].endswith("B finished")


def test_a_history_row_cut_short_is_not_read(tmp_path):
    run = _training(tmp_path, KEYS[0], epochs=2)
    with open(run / "history.csv", "a") as history:
        history.write("epochs,3,21,1.0,0.4")                    # being written
    assert last_epoch(run) == (2.0, 2.0)
    assert last_epoch(tmp_path / "nothing") == (0.0, None)


@pytest.mark.parametrize("width", [150, 80])
def test_the_live_panel_shows_each_running_run_on_a_terminal(tmp_path, width):
    """Each running run by a name that tells it from the others, whole, at 80 columns too
    (issue 66: every name was cut to ``runs/revised/bidirectional/AP…``)."""
    from rich.console import Console

    screen = io.StringIO()
    console = Console(file=screen, force_terminal=True, width=width)
    keys = [RunKey("revised", "bidirectional", "APoc", "gradnorm", seed, fold)
            for seed in (0, 1) for fold in "BC"] + [
        RunKey("original", "forward", "APoc", "gradnorm", 0, "B")]
    for key in keys:
        _training(tmp_path, key, epochs=3)
    queued = RunKey("revised", "bidirectional", "APoc", "gradnorm", 2, "B")
    progress = Progress(6, 0, print, {k: 10.0 for k in [*keys, queued]}, out=tmp_path,
                        live=console)
    with progress.watching(every=0.05):
        progress.poll()
        console.print("a log line")
    shown = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", screen.getvalue())
    assert "a log line" in shown and "0/6 done, 5 running, 1 queued" in shown
    rows = {re.split(r"\s*[━╺]", line.strip())[0] for line in shown.splitlines()
            if "epoch 3/10" in line}
    assert rows == {run_label(key) for key in keys} and len(rows) == len(keys)
    assert max(map(len, shown.splitlines())) <= width
    assert run_label(keys[-1]) == "original/forward/APoc-gradnorm seed0 B"


@pytest.mark.parametrize("term, panel", [("xterm-256color", True), ("dumb", False)])
def test_a_dumb_terminal_gets_plain_lines_not_a_panel_it_cannot_draw(monkeypatch, term, panel):
    """``TERM=dumb`` cannot redraw lines: the live panel would show nothing there (issue 66), so
    the grid prints its plain status lines instead (``live_console`` is None)."""
    from rich.console import Console

    monkeypatch.setenv("TERM", term)
    console = Console(file=io.StringIO(), force_terminal=True)
    assert (live_console(console) is console) == panel


def _dies_once(payload, keys, out, cores, command):
    """A job whose first attempt kills its worker process (as the OOM killer would)."""
    marker = Path(out) / f"attempted-{keys[0]['fold']}"
    if keys[0]["fold"] == "C" and not marker.exists():
        marker.touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return []


def _always_dies(payload, keys, out, cores, command):
    os.kill(os.getpid(), signal.SIGKILL)


@pytest.mark.parametrize("job,survives", [(_dies_once, True), (_always_dies, False)])
def test_a_local_worker_that_dies_is_named_and_its_runs_re_queued(job, survives, tmp_path,
                                                                monkeypatch):
    monkeypatch.setattr(executors, "run_job", job)
    lines = []
    groups = [[key] for key in KEYS[:2]]
    progress = Progress(2, 0, lines.append, {k: 1.0 for k in KEYS[:2]})
    executors._run_local({}, groups, tmp_path, 1, 1, progress, jobs_per_worker=1)
    lost = [line for line in lines if "worker lost" in line]
    assert lost and "killed by SIGKILL" in lost[0] and "re-queued" in lost[0]
    assert str(KEYS[1].path()) in lost[0]
    if survives:
        assert len(lost) == 1 and not progress.failed and progress.done == 2
    else:
        assert len(lost) == executors.MAX_WORKER_LOSSES - 1
        assert {key for key, _ in progress.failed} == set(KEYS[:2])
        assert "died 3 times (the last: local worker process" in progress.failed[0][1]


class FakeDask:
    """The two calls ``DaskWorkers`` makes of a ``dask.distributed.Client``."""

    def __init__(self):
        self.workers = {"tcp://a:1": ["runs-B"], "tcp://b:1": ["runs-C", "runs-x"]}

    def scheduler_info(self, n_workers=5):
        return {"workers": {w: {} for w in self.workers}}

    def processing(self):
        return {w: tuple(jobs) for w, jobs in self.workers.items()}


def test_a_dask_worker_that_leaves_is_named_with_the_runs_it_trained():
    client, lines = FakeDask(), []
    progress = Progress(2, 0, lines.append, {k: 1.0 for k in KEYS[:2]})
    workers = executors.DaskWorkers(client, {"runs-B": [KEYS[0]], "runs-C": [KEYS[1]]},
                                    progress)
    workers.check()
    assert lines == []
    del client.workers["tcp://b:1"]
    workers.check()
    assert lines == [f"[grid] worker lost: Dask worker tcp://b:1; re-queued (they resume from "
                     f"their last checkpoints): {KEYS[1].path()}"]
