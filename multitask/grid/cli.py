"""``multitask-grid``: run the leave-one-user-out grid of a spec, resumably, locally or on Dask.

    multitask-grid --spec results/quick.toml --out runs/quick --workers 2
    multitask-grid --out runs/converged                # the paper's grid at the default preset
    multitask-grid --spec S.toml --out /shared/grid --scheduler tcp://head:8786

Re-running the same command skips finished runs and resumes interrupted ones; tables come from
``multitask-tables paper DIR``. The grid folder records its spec (grid.json); another spec over
it stops with the differences unless ``--restart``. One grid process per folder (a lock);
Ctrl-C stops every run at once, resumably.

While it trains, the grid shows runs done / running / queued, each running run's epoch and ETA
and the grid's ETA: a live panel on a terminal, else (a file, a pipe, ``TERM=dumb``) a status
line a minute when it changed
(``multitask.grid.progress``); a worker that dies is named, and its runs re-queued.
``--mlflow URI`` logs the grid to MLflow as a parent run and each run as it finishes
(``rnn_seg.runs.tracking``).

``--archive DIR`` keeps the grid's scores archive (``multitask.grid.archive``; what
``multitask-tables archive GRID DIR`` writes) up to date: written once before training, which
checks that DIR may hold it, and again after every job whose runs finished. A grid on scratch
space that may not outlive the job thus loses no finished run's scores; an archive that cannot be
written later is a warning, and training goes on.

    multitask-grid --spec results/paper/spec.toml --out runs/paper --archive results/paper/grid
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from functools import partial
from pathlib import Path
from typing import Callable

from baseline.options import add_threads_argument
from jigsaws_tools.cli.arg_types import non_negative_int, positive_int, thread_count
from jigsaws_tools.cli.common import (Interrupted, command_parser, deprecated_alias,
                                      import_tensorflow, run_command)
from jigsaws_tools.cli.options import DEFAULT_DATA_DIR_TEXT
from jigsaws_tools.errors import WriteFailed
from jigsaws_tools.recording_format import RELEASE_LAYOUT_ONLY
from rnn_seg.config import LOOPS, RUNNABLE_LOOPS, require_native_precision
from rnn_seg.encoders.config import SCHEDULES
from rnn_seg.encoders.import_path import is_import_path
from rnn_seg.runs.folder import RunFolderError, is_finished
from rnn_seg.runs.outputs import OutputFolderError, check_output_folder, folders_below
from rnn_seg.runs.provenance import set_command

from .folder import GRID_RECORD, read_record
from .spec import (DEFAULT_PRESET, PRESETS, GridSpec, expand, job_groups, load_spec,
                   release_users, with_budget, with_overrides)

PROG = "multitask-grid"


def build_parser() -> argparse.ArgumentParser:
    parser = command_parser(PROG, __doc__)
    parser.add_argument("--spec", type=Path, metavar="TOML",
                        help="grid spec (keys in multitask/grid/spec.py; default: the preset's "
                             "whole paper grid)")
    parser.add_argument("--preset", choices=list(PRESETS),
                        help="override the spec's preset (budget: width, schedule, seeds; "
                             f"default: the spec's, else {DEFAULT_PRESET})")
    parser.add_argument("--data-dir", metavar="DIR",
                        help="override the spec's data_dir: a release folder or 'synthetic' "
                             f"(default: the spec's, else {DEFAULT_DATA_DIR_TEXT})")
    parser.add_argument("--loops", choices=LOOPS,
                        help="override the spec's loops: how the LSTM's loops over time run "
                             "(graph: TensorFlow ops; xla: compiled by XLA; fused: C++ ops built "
                             "on first use; auto: fused where they build, else graph; same "
                             "results to float32 rounding; a grid may resume with any; default: "
                             "the spec's, else auto: graph with --stack, and on resuming a grid "
                             "the loops its grid.json records)")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="grid folder (shared by every worker on Dask)")
    parser.add_argument("--workers", type=non_negative_int, default=1, metavar="N",
                        help="local worker processes, at most the cores this process may use; "
                             "0 = none, each job in this process in turn (no worker start-up: "
                             "small grids, a debugger)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="Dask scheduler address (tcp://host:8786): run the jobs on that "
                             "cluster (default: none, local workers)")
    threads = add_threads_argument(parser, "cores per run (default: 0 = the usable cores / "
                                           "--workers locally, 1 on Dask)", this_machine=False)
    deprecated_alias(parser, "--threads-per-job", threads)
    parser.add_argument("--stack", type=positive_int, default=1, metavar="N",
                        help="train up to N runs of one configuration (folds, seeds) together in "
                             "one vectorised step per job; pays for small models "
                             "(docs/PERFORMANCE.md)")
    parser.add_argument("--archive", type=Path, metavar="DIR",
                        help="keep the grid's scores archive in DIR up to date: before training "
                             "and after every finished job (default: none; multitask-tables "
                             "archive GRID DIR writes it once)")
    parser.add_argument("--mlflow", metavar="URI",
                        help="also log the grid to MLflow: a parent run (the spec) and each run "
                             "as it finishes, nested under it (settings, per-epoch metrics, "
                             "final scores; needs pip install -e '.[mlflow]'; default: none)")
    parser.add_argument("--dry-run", action="store_true",
                        help="list the runs still to run, in the order they run, and stop")
    parser.add_argument("--restart", action="store_true",
                        help="make this spec the grid's even if grid.json records another; run "
                             "folders of other settings are trained afresh, finished runs of "
                             "the same settings are kept")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.scheduler and importlib.util.find_spec("distributed") is None:
        parser.error("--scheduler needs Dask: pip install 'mtrnn-jigsaws[dask]'")
    set_command([PROG, *(sys.argv[1:] if argv is None else argv)])
    return run_command(PROG, args.verbose, lambda: _run(args),
                       layout_advice=RELEASE_LAYOUT_ONLY, argv=argv)


def _check_grid_folder(out: Path) -> None:
    """Refuse an ``--out`` that is a run folder or lies among a run's files
    (``check_output_folder``), or that holds a run or grid folder anywhere but at a grid's own
    places, under ``out/runs/`` (a grid of an earlier version has no grid.json to show it)."""
    check_output_folder(out, PROG, may_be_grid=True, may_hold=True)
    if not Path(out).is_dir():
        return
    own = Path(out).resolve() / "runs"
    for path, kind in folders_below(Path(out).resolve()):
        if kind == "grid folder" or not path.is_relative_to(own):
            raise OutputFolderError(f"{out} holds a {kind} ({path}) outside a grid's runs/; "
                                    f"{PROG} does not write over it (choose another output "
                                    "folder)")


def _on_recorded_loops(spec: GridSpec, out: Path) -> GridSpec:
    """``spec``, or, where it asks for ``auto`` loops and ``out``'s grid.json records the runnable
    loops the grid was launched with (say ``graph``, the default before ``auto``), ``spec`` on
    those after a line saying so: a resumed grid keeps one path (``multitask-tables
    execution`` refuses two), and its runs already started keep theirs too
    (``RecurrentEncoder.resume_on``). ``--loops`` other than ``auto`` switches."""
    if spec.encoder != "lstm" or spec.loops != "auto":
        return spec
    record = read_record(out)
    recorded = (record or {}).get("spec", {}).get("loops")
    if recorded not in RUNNABLE_LOOPS:
        return spec
    print(f"grid: loops auto: {recorded}, the loops {out / GRID_RECORD} records (--loops to "
          "switch)", flush=True)
    return with_overrides(spec, loops=recorded)


def _run(args: argparse.Namespace) -> int:
    from rnn_seg.runs.lock import hold_folder

    spec = load_spec(args.spec) if args.spec else GridSpec()
    spec = with_overrides(spec, preset=args.preset, data_dir=args.data_dir, loops=args.loops)
    spec = with_budget(spec.with_absolute_paths())              # as recorded, one path
    if is_import_path(spec.encoder):     # finding a user's encoder module imports its package,
        import_tensorflow()              # which may import TensorFlow: quietly, before that
    if not args.scheduler:                       # a cluster's workers have their own CPUs
        require_native_precision(spec.precision)
        for option, count, note in (
                ("--threads", args.threads, " (with --scheduler, each worker checks its own)"),
                ("--workers", args.workers, " (one TensorFlow process per worker)")):
            try:
                thread_count(str(count))
            except argparse.ArgumentTypeError as error:
                raise ValueError(f"{option}: {error}{note}") from None
    if args.stack > 1 and spec.fold_settings:
        raise ValueError("--stack trains runs of one setting in one vectorised step; this "
                         "spec's fold_settings give folds settings of their own: use --stack 1")
    if args.stack > 1 and spec.loops == "auto":
        spec = with_overrides(spec, loops="graph")     # what a vectorised step runs
    if args.stack > 1 and spec.loops != "graph":
        raise ValueError(f"--stack vectorises the runs' steps, which turns {spec.loops}'s "
                         f"compiled loops back into TensorFlow ops: use --stack 1 with loops "
                         f"{spec.loops} (or graph loops with --stack)")
    _check_grid_folder(args.out)
    spec = _on_recorded_loops(spec, args.out)
    users = release_users(spec)
    try:
        keys = expand(spec, users)
    except ValueError as error:                 # folds the release lacks: the spec's
        raise ValueError(f"{args.spec}: {error}" if args.spec else str(error)) from None
    budget = spec.budget
    size = f"H={budget.hidden}" if spec.encoder == "lstm" else f"encoder {spec.encoder}"
    schedule = (f"{spec.epochs} epochs" if spec.encoder in SCHEDULES and spec.epochs
                else budget.describe_schedule())
    print(f"grid: task {spec.task}, preset {spec.preset}, {size}, "
          f"schedule {schedule}, seeds {sorted({k.seed for k in keys})}, "
          f"data {spec.data_dir}", flush=True)
    if spec.inner_validation is not None:
        print(f"inner runs: {spec.inner_validation} validation user(s) per outer fold, each "
              "scored on its validation user with the outer fold's user held out (folders "
              "<outer>-val-<validation>)", flush=True)
    if spec.fold_settings:
        print("settings per outer fold (a nested selection): " + "; ".join(
            f"{fold} " + (", ".join(f"{k} {json.dumps(v)}" for k, v in entry.items())
                          or "the spec's")
            for fold, entry in spec.fold_settings.items()) + "; any other fold the spec's",
            flush=True)
    if args.dry_run:
        return _dry_run(args, spec, keys)
    tracker = None
    if args.mlflow:
        from rnn_seg.runs.tracking import Tracker
        tracker = Tracker(args.mlflow)                       # checked before any work
    from .executors import run_grid              # TensorFlow: only where a job trains (run_job)
    from .progress import live_console
    from .record import prepare_grid
    from .spec import spec_payload

    def log(message: str) -> None:
        print(message, flush=True)

    status = "FAILED"
    try:
        with hold_folder(args.out, "grid folder"):
            prepare_grid(args.out, spec, keys, args.restart, log)
            after_job = after_run = None
            if args.archive:
                _archive(args.out, args.archive, log)          # an error here stops the grid
                after_job = partial(_archive, args.out, args.archive, log, warn=True)
            if tracker is not None:
                tracker.start_grid(args.out, spec_payload(spec))
                after_run = partial(_track, tracker, log)
                for key in keys:                 # finished before: logged unless they were
                    if is_finished(args.out / key.path()):
                        after_run(args.out / key.path())
            failed = run_grid(spec, keys, args.out, args.workers, args.scheduler, args.threads,
                              args.stack, log=log, after_job=after_job, after_run=after_run,
                              live=live_console())
            status = "FAILED" if failed else "FINISHED"
    except KeyboardInterrupt:
        status = "KILLED"
        raise Interrupted(f"{PROG}: interrupted: queued runs cancelled, running ones stopped; "
                          "run the same command again to resume") from None
    finally:
        if tracker is not None:
            tracker.end_grid(status)
    if failed:
        print(f"{PROG}: {len(failed)} run(s) failed (re-run to retry):", file=sys.stderr)
        for key, message in failed:
            print(f"  {key.path()}: {message}", file=sys.stderr)
        return 1
    tables = (f"multitask-tables paper {args.out}" if spec.inner_validation is None
              else f"multitask-tables factors BASELINE {args.out} (a factor's level) or "
                   f"multitask-tables ladder {args.out} --lengths N... (pilot runs)")
    print(f"grid complete: {len(keys)} runs in {args.out}; tables: {tables}")
    return 0


def _dry_run(args: argparse.Namespace, spec: GridSpec, keys: list) -> int:
    """What the launch would do over ``--out``, decided by its own checks, writing nothing: its
    lock, its record and run folders (``record.plan_launch``: another spec or runs of other
    settings refused as the launch refuses them), the archive folder as it would be checked after
    them; then each run it would train, resume or train afresh, in the order they run."""
    from rnn_seg.runs.folder import trained_units
    from rnn_seg.runs.lock import check_free

    from .record import plan_launch

    check_free(args.out, "grid folder")
    cleared, record = plan_launch(args.out, spec, keys, args.restart)
    afresh = {str(key.path()) for key in cleared}
    if args.archive:                                  # refused now, as it would be then
        from .archive import check_destination
        check_destination(args.out, args.archive,
                          {**record, "runs": [r for r in record["runs"] if r not in afresh]})
        print(f"archive: {args.archive} would be kept up to date (not written in a dry run)")
    pending = [key for key in keys
               if str(key.path()) in afresh or not is_finished(args.out / key.path())]
    resumed = 0
    for group in job_groups(pending, args.stack, grid=keys):    # in the order they run
        for key in group:
            done = 0.0 if str(key.path()) in afresh else trained_units(args.out / key.path())
            resumed += done > 0
            note = (" (other settings: cleared, trained afresh)" if str(key.path()) in afresh
                    else f" (resumes after {done:g} of its epochs)" if done else "")
            print(f"{key.path()}{note}")
    started = len(pending) - resumed - len(afresh)
    parts = [f"{count} {what}" for count, what in ((started, "new"), (resumed, "resumed"), (
        len(afresh), "of other settings, trained afresh")) if count]
    print(f"{len(keys)} runs, {len(keys) - len(pending)} already finished, "
          f"{len(pending)} to run" + (f" ({', '.join(parts)})" if parts else ""))
    return 0


def _track(tracker, log: Callable[[str], None], run_dir: Path) -> None:
    """Log a run that finished to MLflow (``rnn_seg.runs.tracking``); a failure is a warning
    line, and training goes on."""
    try:
        tracker.log_run(run_dir)
    except Exception as error:                        # MLflow's errors have no common base
        log(f"[grid] warning: {run_dir} was not logged to MLflow at {tracker.uri}: "
            f"{type(error).__name__}: {error}")


def _archive(out: Path, dest: Path, log: Callable[[str], None], warn: bool = False) -> None:
    """Write the scores archive of the grid ``out`` to ``dest`` and say so; with ``warn`` (after
    each job), a failure is a warning line instead of an error, and the archive's notes, said
    before training, are not said again."""
    from .archive import archive_grid

    try:
        finished, recorded = archive_grid(out, dest, notes=not warn)
    except (OSError, RunFolderError, WriteFailed) as error:     # WriteFailed: a full disk
        if not warn:
            raise
        log(f"[grid] warning: the archive in {dest} was not updated: {error}")
        return
    log(f"[grid] archive {dest}: {finished} of {recorded} runs")


if __name__ == "__main__":
    sys.exit(main())
