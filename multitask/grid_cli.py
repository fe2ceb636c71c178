"""``multitask-grid``: run the leave-one-user-out grid of a spec, resumably, locally or on Dask.

    multitask-grid --spec results/quick.toml --out runs/quick --workers 2 --stack 4
    multitask-grid --preset quick --out runs/quick                   # the default paper grid
    multitask-grid --spec S.toml --out /shared/grid --scheduler tcp://head:8786

Re-running the same command skips finished runs and resumes interrupted ones; tables come from
``multitask-tables DIR``. The grid folder records its spec (grid.json); another spec over it stops
with the differences unless ``--restart``. One grid process per folder (a lock); Ctrl-C stops
every run at once, resumably.
"""
from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path

from jigsaws_tools.errors import JigsawsError
from rnn_seg.folder_lock import hold_folder
from rnn_seg.provenance import set_command
from rnn_seg.rundir import RunFolderError

from .grid_executors import run_grid
from .grid_record import prepare_grid
from .grid_spec import (PRESETS, GridSpec, expand, load_spec, release_users, with_budget,
                        with_overrides)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="multitask-grid", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spec", type=Path, help="TOML grid spec (see multitask.grid_spec)")
    parser.add_argument("--preset", choices=list(PRESETS), help="override the spec's preset")
    parser.add_argument("--out", type=Path, required=True, help="grid folder (shared on Dask)")
    parser.add_argument("--workers", type=int, default=1, help="local worker processes")
    parser.add_argument("--scheduler", help="Dask scheduler address: run the jobs on that cluster")
    parser.add_argument("--threads-per-job", type=int, default=0,
                        help="cores per run (default: cores / workers locally, 1 on Dask)")
    parser.add_argument("--stack", type=int, default=1,
                        help="train up to N runs of one configuration (folds, seeds) together in "
                             "one vectorised step per job; pays for small models "
                             "(docs/PERFORMANCE.md)")
    parser.add_argument("--dry-run", action="store_true", help="list the runs and stop")
    parser.add_argument("--restart", action="store_true",
                        help="make this spec the grid's even if grid.json records another; run "
                             "folders of other settings are trained afresh, finished runs of "
                             "the same settings are kept")
    return parser


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    logging.basicConfig(format="%(levelname)s: %(message)s", level=logging.WARNING)
    args = build_parser().parse_args(argv)
    set_command(["multitask-grid", *(sys.argv[1:] if argv is None else argv)])
    if min(args.workers, args.stack) < 1:
        print("multitask-grid: error: --workers and --stack must be >= 1", file=sys.stderr)
        return 2
    try:
        spec = load_spec(args.spec) if args.spec else GridSpec()
        spec = with_overrides(spec, preset=args.preset)
        spec = with_budget(spec.with_absolute_paths())              # as recorded, one path
        keys = expand(spec, release_users(spec))
    except (JigsawsError, ValueError, OSError) as error:
        print(f"multitask-grid: error: {error}", file=sys.stderr)
        return 2
    budget = spec.budget
    print(f"grid: task {spec.task}, preset {spec.preset}, H={budget.hidden}, "
          f"schedule x{budget.schedule_scale:g}, seeds {list(budget.seeds)}, data {spec.data}",
          flush=True)
    if args.dry_run:
        for key in keys:
            print(key.path())
        print(f"{len(keys)} runs")
        return 0
    def log(message: str) -> None:
        print(message, flush=True)

    try:
        with hold_folder(args.out, "grid folder"):
            prepare_grid(args.out, spec, keys, args.restart, log)
            failed = run_grid(spec, keys, args.out, args.workers, args.scheduler,
                              args.threads_per_job, args.stack, log=log)
    except (JigsawsError, ValueError, OSError, RunFolderError) as error:
        print(f"multitask-grid: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("multitask-grid: interrupted: queued runs cancelled, running ones stopped; run the "
              "same command again to resume", file=sys.stderr)
        return 130
    if failed:
        print(f"multitask-grid: {len(failed)} run(s) failed (re-run to retry):", file=sys.stderr)
        for key, message in failed:
            print(f"  {key.path()}: {message}", file=sys.stderr)
        return 1
    print(f"grid complete: {len(keys)} runs in {args.out}; tables: multitask-tables {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
