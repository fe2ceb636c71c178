"""``multitask-grid``: run the leave-one-user-out grid of a spec, resumably, locally or on Dask.

    multitask-grid --spec results/quick.toml --out runs/quick --workers 2 --stack 4
    multitask-grid --preset quick --out runs/quick                   # the default paper grid
    multitask-grid --spec S.toml --out /shared/grid --scheduler tcp://head:8786

Re-running the same command skips finished runs and resumes interrupted ones; tables come from
``multitask-tables DIR``.
"""
from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path

from jigsaws_tools.errors import JigsawsError
from rnn_seg.rundir import write_json

from .grid_spec import PRESETS, GridSpec, expand, load_spec, release_users, spec_payload, with_overrides
from .grid_executors import run_grid


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
    return parser


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    logging.basicConfig(format="%(levelname)s: %(message)s", level=logging.WARNING)
    args = build_parser().parse_args(argv)
    if min(args.workers, args.stack) < 1:
        print("multitask-grid: error: --workers and --stack must be >= 1", file=sys.stderr)
        return 2
    try:
        spec = load_spec(args.spec) if args.spec else GridSpec()
        spec = with_overrides(spec, preset=args.preset)
        spec = spec.with_absolute_paths()                                   # workers see one path
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
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "grid.json", {"spec": spec_payload(spec),
                                       "runs": [str(k.path()) for k in keys]})
    failed = run_grid(spec, keys, args.out, args.workers, args.scheduler, args.threads_per_job,
                      args.stack, log=lambda m: print(m, flush=True))
    if failed:
        print(f"multitask-grid: {len(failed)} run(s) failed (re-run to retry):", file=sys.stderr)
        for key, message in failed:
            print(f"  {key.path()}: {message}", file=sys.stderr)
        return 1
    print(f"grid complete: {len(keys)} runs in {args.out}; tables: multitask-tables {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
