"""Run a grid's jobs: a local pool of worker processes, or an existing Dask cluster.

Each job is ``job.run_job`` on a group of up to ``stack`` run directories of one configuration
(trained together in one vectorised step, ``rnn_seg.stack``; 1 = each run alone); finished runs
(``finished.json``) are skipped, interrupted ones resume from their checkpoints inside the job.
What the grid shows meanwhile (runs done / running / queued, epochs, ETAs) is
``progress.Progress``'s, read from the run folders. A worker that dies is named and its runs
re-queued (they resume from their checkpoints): a local worker process that ends abruptly breaks
its pool, and the jobs that had not finished run again on a fresh one, each at most
``MAX_WORKER_LOSSES`` times; on Dask the scheduler re-queues them (its ``allowed-failures``) and
the grid says which worker left and with which runs.

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
from collections import Counter
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict
from pathlib import Path
from typing import Callable

from jigsaws_tools.cores import usable_cores
from rnn_seg.runs.provenance import command
from rnn_seg.runs.folder import is_finished, trained_units
from rnn_seg.threads import thread_plan

from .job import run_job
from .progress import STATUS_EVERY, Progress
from .spec import GridSpec, RunKey, job_groups, schedule_epochs, spec_payload

Log = Callable[[str], None]

#: Times a job may lose its local worker process before it counts as failed (Dask's default
#: ``allowed-failures`` is the same).
MAX_WORKER_LOSSES = 3


#: Jobs a local worker process runs before a fresh one replaces it (when every job of the grid
#: has the same thread plan; else one).
JOBS_PER_WORKER = 16


def run_grid(spec: GridSpec, keys: list[RunKey], out: Path, workers: int = 1,
             scheduler: str | None = None, cores_per_job: int = 0, stack: int = 1,
             log: Log = print, after_job: Callable[[], None] | None = None,
             after_run: Callable[[Path], None] | None = None, live=None,
             status_every: float = STATUS_EVERY) -> list[tuple[RunKey, str]]:
    """Run every unfinished run of ``keys`` under ``out``. Check the folders first
    (``record.prepare_grid``): a finished run counts as done here.

    Args:
        spec: the grid's budget, data and experiments.
        keys: the runs to train (``spec.expand``).
        out: the grid's folder; on Dask, a folder every worker sees at the same path.
        workers: local worker processes (ignored with ``scheduler``); 0 = none: each job
            runs in this process, one after another (``_run_here``).
        scheduler: address of a Dask scheduler (``tcp://host:8786``); None = a local pool.
        cores_per_job: TensorFlow threads of each job; 0 = the cores this process may use /
            ``workers`` locally (all of them with none), 1 on Dask (start workers with one
            thread each).
        stack: runs of one configuration per job, trained in one vectorised step.
        log: where the progress lines go.
        after_job: called in this process after each job whose runs finished.
        after_run: called in this process with the folder of each run trained to the end.
        live: a ``rich`` console to show the grid's state on (a terminal); None = plain status
            lines every ``status_every`` seconds (``progress.Progress``).

    Returns:
        The failures, ``(key, "ExceptionType: message")`` each.
    """
    out = Path(out).resolve()
    pending = [k for k in keys if not is_finished(out / k.path())]
    log(f"[grid] {len(keys)} runs, {len(keys) - len(pending)} already finished, "
        f"{len(pending)} to run"
        + (f" on {scheduler}" if scheduler else
           f" with {workers} worker(s)" if workers else " in this process"))
    if not pending:
        return []
    payload = spec_payload(spec)
    groups = job_groups(pending, stack, grid=keys)
    progress = Progress(len(keys), len(keys) - len(pending), log,
                        {key: _epochs_left(spec, key, out) for key in pending},
                        after_job=after_job, out=out, after_run=after_run, live=live,
                        epochs={key: float(schedule_epochs(spec, key)) for key in pending},
                        status_every=status_every)
    if scheduler:
        _run_dask(payload, groups, out, scheduler, cores_per_job or 1, progress)
    else:
        with progress.watching():
            if workers == 0:
                _run_here(payload, groups, out, cores_per_job, progress)
            else:
                cores = cores_per_job or max(1, usable_cores() // workers)
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


def _run_here(payload: dict, groups: list[list[RunKey]], out: Path, cores: int,
              progress: Progress) -> None:
    """Run ``groups`` one after another in this process (``--workers 0``): no worker process
    starts TensorFlow and the project anew (several seconds a worker, more than a small grid's
    runs take), and a debugger or profiler sees the runs. A job that fails is reported as a
    worker's failure is, and the next one runs; Ctrl-C stops the running job where it is, and its
    runs resume from their checkpoints next time. TensorFlow fixes its thread pools at this
    process's first op, so ``cores`` applies only if no job ran here before
    (``rnn_seg.threads.configure_threads``)."""
    for group in groups:
        try:
            run_job(*_job_args(payload, group, out, cores))
        except Exception as error:                     # as a worker's job would end
            progress.finished_group(group, error)
        else:
            progress.finished_group(group)


def _run_local(payload: dict, groups: list[list[RunKey]], out: Path, workers: int, cores: int,
               progress: Progress, jobs_per_worker: int) -> None:
    """Run ``groups`` on local worker processes (``_run_pools``); the jobs a dead worker broke
    off run again on fresh ones, each at most ``MAX_WORKER_LOSSES`` times, after which its runs
    count as failed."""
    losses: Counter[int] = Counter()
    queue = list(range(len(groups)))
    while queue:
        lost, cause = _run_pools(payload, [groups[i] for i in queue], out, workers, cores,
                                 progress, jobs_per_worker)
        queue = [queue[i] for i in lost]
        losses.update(queue)
        given_up = [i for i in queue if losses[i] >= MAX_WORKER_LOSSES]
        queue = [i for i in queue if losses[i] < MAX_WORKER_LOSSES]
        if queue:
            progress.worker_lost(cause, [key for i in queue for key in groups[i]])
        for i in given_up:
            progress.finished_group(groups[i], WorkerLost(
                f"its worker process died {MAX_WORKER_LOSSES} times (the last: {cause})"))


class WorkerLost(RuntimeError):
    """A job's worker ended before the job did, too many times."""


def _run_pools(payload: dict, groups: list[list[RunKey]], out: Path, workers: int, cores: int,
               progress: Progress, jobs_per_worker: int) -> tuple[list[int], str]:
    """Local worker processes, each running up to ``jobs_per_worker`` jobs in turn before a fresh
    one replaces it: TensorFlow starts once per worker and compiled loops are reused, while a
    job's results do not depend on the jobs before it in its process (tested), and whatever
    TensorFlow keeps from one job to the next stays bounded. Workers that run several jobs come
    in a fresh pool for every ``workers * jobs_per_worker`` jobs: a pool that replaces its own
    workers after more than one job (``max_tasks_per_child`` > 1) can stop starting them before
    Python 3.13 (CPython issue 115634), and the grid would wait forever.

    Returns:
        The indices into ``groups`` of the jobs a worker's death broke off (none ran after it
        in the same pool), and what ended that worker.
    """
    if jobs_per_worker == 1:
        return _run_pool(payload, groups, out, workers, cores, progress, max_tasks_per_child=1)
    chunk = workers * jobs_per_worker
    lost, cause = [], ""
    for start in range(0, len(groups), chunk):
        broken, why = _run_pool(payload, groups[start:start + chunk], out, workers, cores,
                                progress)
        lost += [start + i for i in broken]
        cause = why or cause
    return lost, cause


def _run_pool(payload: dict, groups: list[list[RunKey]], out: Path, workers: int, cores: int,
              progress: Progress, max_tasks_per_child: int | None = None
              ) -> tuple[list[int], str]:
    """Run ``groups`` on one pool of ``workers`` fresh processes (``run_job`` each); returns the
    indices of the jobs broken off by a worker that died, and how it ended."""
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                               max_tasks_per_child=max_tasks_per_child, initializer=_init_worker,
                               initargs=(os.getpid(),))
    lost = []
    try:
        futures = {pool.submit(run_job, *_job_args(payload, group, out, cores)): i
                   for i, group in enumerate(groups)}
        processes, ended = pool._processes, []      # the pool's own dict (no public API)
        for future in as_completed(futures):
            error = future.exception()
            if isinstance(error, BrokenProcessPool):
                ended = ended or list((processes or {}).values())
                lost.append(futures[future])
            else:
                progress.finished_group(groups[futures[future]], error)
    except BaseException:
        _stop_pool(pool)
        raise
    pool.shutdown()
    return sorted(lost), (_how_ended(ended) if lost else "")


def _how_ended(processes: list) -> str:
    """``local worker process 1234 (killed by SIGKILL)``: the first that died of other causes
    than the pool's own termination of the rest after it."""
    for process in processes:
        code = process.exitcode
        if code not in (None, 0, -signal.SIGTERM):
            how = (f"killed by {signal.Signals(-code).name}" if code < 0
                   else f"exit code {code}")
            return f"local worker process {process.pid} ({how})"
    return "a local worker process (ended abruptly)"


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
        workers = DaskWorkers(client, {f.key: g for f, g in futures.items()}, progress)
        try:
            with progress.watching(workers.check):
                for future in dask_completed(futures):
                    progress.finished_group(futures[future], future.exception())
        except BaseException:
            client.cancel(list(futures))
            raise


class DaskWorkers:
    """Watches a Dask cluster's workers for the grid: when one leaves while it trains some of
    the grid's jobs, says which worker and which runs (the scheduler re-queues them).

    Args:
        client: the grid's ``dask.distributed.Client``.
        jobs: the grid's runs by their job's task key.
        progress: where it is said (``Progress.worker_lost``).
    """

    def __init__(self, client, jobs: dict[str, list[RunKey]], progress: Progress):
        self.client, self.jobs, self.progress = client, jobs, progress
        self.workers = set(client.scheduler_info(n_workers=-1)["workers"])
        self.processing: dict[str, list[str]] = {}

    def check(self) -> None:
        """Compare the workers with those of the last check (called every few seconds)."""
        workers = set(self.client.scheduler_info(n_workers=-1)["workers"])
        for worker in sorted(self.workers - workers):
            runs = [key for job in self.processing.get(worker, ()) if job in self.jobs
                    for key in self.jobs[job]]
            self.progress.worker_lost(f"Dask worker {worker}", runs)
        self.workers = workers
        self.processing = {w: [str(job) for job in jobs]
                           for w, jobs in self.client.processing().items()}
