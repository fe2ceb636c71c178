"""Run a grid's jobs: a local pool of worker processes, or an existing Dask cluster.

Each job is ``job.run_job`` on a group of up to ``stack`` run directories of one configuration
(trained together in one vectorised step, ``rnn_seg.stack``; 1 = each run alone); finished runs
(``finished.json``) are skipped, interrupted ones resume from their checkpoints inside the job.
Progress lines give done/total and an ETA: the wall time per epoch of the runs finished in this
invocation times the epochs left (runs differ: Pr 80 epochs, APoc 180 at the converged preset;
a run resumed from a checkpoint counts only the epochs after it).

Local workers die with the grid process (``PR_SET_PDEATHSIG`` on Linux, a watchdog thread
elsewhere) and ignore Ctrl-C: on Ctrl-C the grid cancels the queued jobs, stops the running ones
at once and re-raises ``KeyboardInterrupt``; every interrupted run resumes from its last
checkpoint next time. On Dask, queued jobs are cancelled; running ones end on their workers.
"""
from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict
from datetime import timedelta
from pathlib import Path
from typing import Callable

from rnn_seg.runs.provenance import command
from rnn_seg.runs.folder import is_finished, trained_units
from rnn_seg.threads import thread_plan

from .job import run_job
from .spec import GridSpec, RunKey, job_groups, schedule_epochs, spec_payload

Log = Callable[[str], None]


class Progress:
    """Counts runs and prints one line per finished run. The ETA is the wall time per unit of
    work finished in this invocation (parallelism included) times the work left; a run's work
    is its ``weights`` entry (its schedule's epochs), one per run to train. ``after_job`` is
    called after every job that trained a run to the end (e.g. to archive the grid)."""

    def __init__(self, total: int, already: int, log: Log, weights: dict[RunKey, float],
                 clock: Callable[[], float] = time.monotonic,
                 after_job: Callable[[], None] | None = None):
        self.total, self.done, self.log, self.clock = total, already, log, clock
        self.weights, self.started, self.after_job = weights, clock(), after_job
        self.work_left, self.work_done = float(sum(weights.values())), 0.0
        self.failed: list[tuple[RunKey, str]] = []

    def finished_group(self, keys: list[RunKey], error: BaseException | None = None) -> None:
        for key in keys:
            self.finished(key, error)
        if self.after_job and not error:
            self.after_job()

    def finished(self, key: RunKey, error: BaseException | None = None) -> None:
        self.done += 1
        work = self.weights[key]
        self.work_done, self.work_left = self.work_done + work, max(0.0, self.work_left - work)
        if error:
            self.failed.append((key, f"{type(error).__name__}: {error}"))
        eta = (timedelta(seconds=round((self.clock() - self.started) / self.work_done
                                       * self.work_left))
               if self.work_done else "unknown")      # only runs with nothing left to train yet
        status = f"FAILED: {self.failed[-1][1]}" if error else "finished"
        self.log(f"[grid] {self.done}/{self.total} done, ETA {eta} | {key.path()} {status}")


#: Jobs a local worker process runs before a fresh one replaces it (when every job of the grid
#: has the same thread plan; else one).
JOBS_PER_WORKER = 16


def run_grid(spec: GridSpec, keys: list[RunKey], out: Path, workers: int = 1,
             scheduler: str | None = None, cores_per_job: int = 0, stack: int = 1,
             log: Log = print, after_job: Callable[[], None] | None = None
             ) -> list[tuple[RunKey, str]]:
    """Run every unfinished run of ``keys`` under ``out``. Check the folders first
    (``record.prepare_grid``): a finished run counts as done here.

    Args:
        spec: the grid's budget, data and experiments.
        keys: the runs to train (``spec.expand``).
        out: the grid's folder; on Dask, a folder every worker sees at the same path.
        workers: local worker processes (ignored with ``scheduler``).
        scheduler: address of a Dask scheduler (``tcp://host:8786``); None = a local pool.
        cores_per_job: TensorFlow threads of each job; 0 = this machine's cores / ``workers``
            locally, 1 on Dask (start workers with one thread each).
        stack: runs of one configuration per job, trained in one vectorised step.
        log: where the progress lines go.
        after_job: called in this process after each job whose runs finished.

    Returns:
        The failures, ``(key, "ExceptionType: message")`` each.
    """
    out = Path(out).resolve()
    pending = [k for k in keys if not is_finished(out / k.path())]
    log(f"[grid] {len(keys)} runs, {len(keys) - len(pending)} already finished, "
        f"{len(pending)} to run"
        + (f" on {scheduler}" if scheduler else f" with {workers} worker(s)"))
    if not pending:
        return []
    payload = spec_payload(spec)
    groups = job_groups(pending, stack, grid=keys)
    progress = Progress(len(keys), len(keys) - len(pending), log,
                        {key: _epochs_left(spec, key, out) for key in pending},
                        after_job=after_job)
    if scheduler:
        _run_dask(payload, groups, out, scheduler, cores_per_job or 1, progress)
    else:
        cores = cores_per_job or max(1, (os.cpu_count() or 1) // workers)
        _run_local(payload, groups, out, workers, cores, progress,
                   jobs_per_worker(spec, groups, cores))
    return progress.failed


def _epochs_left(spec: GridSpec, key: RunKey, out: Path) -> float:
    """Epochs of ``key``'s schedule still to train: all, less those its newest checkpoint holds
    when an earlier launch was interrupted (the ETA's weight of the run)."""
    return max(0.0, schedule_epochs(spec, key) - trained_units(out / key.path()))


def jobs_per_worker(spec: GridSpec, groups: list[list[RunKey]], cores: int) -> int:
    """``JOBS_PER_WORKER`` if every job of ``groups`` has the same thread plan on ``cores``
    cores, else 1: TensorFlow fixes a process's thread pools at its first job."""
    plans = {thread_plan(cores, spec.budget.hidden, spec.precision,
                         bidirectional=group[0].direction == "bidirectional")
             for group in groups}
    return JOBS_PER_WORKER if len(plans) == 1 else 1


def _job_args(payload: dict, group: list[RunKey], out: Path, cores: int) -> tuple:
    return payload, [asdict(key) for key in group], str(out), cores, command()


def _run_local(payload: dict, groups: list[list[RunKey]], out: Path, workers: int, cores: int,
               progress: Progress, jobs_per_worker: int) -> None:
    """Local worker processes, each running up to ``jobs_per_worker`` jobs in turn before a fresh
    one replaces it: TensorFlow starts once per worker and compiled loops are reused, while a
    job's results do not depend on the jobs before it in its process (tested), and whatever
    TensorFlow keeps from one job to the next stays bounded. Workers that run several jobs come
    in a fresh pool for every ``workers * jobs_per_worker`` jobs: a pool that replaces its own
    workers after more than one job (``max_tasks_per_child`` > 1) can stop starting them before
    Python 3.13 (CPython issue 115634), and the grid would wait forever."""
    if jobs_per_worker == 1:
        _run_pool(payload, groups, out, workers, cores, progress, max_tasks_per_child=1)
        return
    chunk = workers * jobs_per_worker
    for start in range(0, len(groups), chunk):
        _run_pool(payload, groups[start:start + chunk], out, workers, cores, progress)


def _run_pool(payload: dict, groups: list[list[RunKey]], out: Path, workers: int, cores: int,
              progress: Progress, max_tasks_per_child: int | None = None) -> None:
    """Run ``groups`` on one pool of ``workers`` fresh processes (``run_job`` each)."""
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                               max_tasks_per_child=max_tasks_per_child, initializer=_init_worker,
                               initargs=(os.getpid(),))
    try:
        futures = {pool.submit(run_job, *_job_args(payload, group, out, cores)): group
                   for group in groups}
        for future in as_completed(futures):
            progress.finished_group(futures[future], future.exception())
    except BaseException:
        _stop_pool(pool)
        raise
    pool.shutdown()


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel the queued jobs and end the running ones now (their runs resume later)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())   # no public API < 3.14
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(timeout=10)


def _init_worker(parent: int) -> None:
    """In each local worker: leave Ctrl-C to the grid process, and die with it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        pr_set_pdeathsig = 1
        if ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGTERM) == 0:
            if os.getppid() != parent:           # the parent died before prctl
                os.kill(os.getpid(), signal.SIGTERM)
            return
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def _watch_parent(parent: int) -> None:
    """Portable fallback of ``PR_SET_PDEATHSIG``: end this process once it is orphaned."""
    while os.getppid() == parent:
        time.sleep(1.0)
    os.kill(os.getpid(), signal.SIGTERM)


def _run_dask(payload: dict, groups: list[list[RunKey]], out: Path, address: str, cores: int,
              progress: Progress) -> None:
    """Submit every run to an existing Dask cluster and collect them as they finish."""
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed
    except ImportError:
        raise RuntimeError("--scheduler needs Dask: pip install 'mtrnn-jigsaws[dask]'") from None
    with Client(address) as client:
        futures = {client.submit(run_job, *_job_args(payload, group, out, cores), pure=False,
                                 key=f"runs-{'-'.join(map(str, asdict(group[0]).values()))}"
                                     f"-x{len(group)}"): group
                   for group in groups}
        try:
            for future in dask_completed(futures):
                progress.finished_group(futures[future], future.exception())
        except BaseException:
            client.cancel(list(futures))
            raise
