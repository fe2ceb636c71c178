"""End-to-end time of LOUO folds at the ``quick`` preset, and the throughput of several at once.

Runs ``multitask-grid`` on fresh folders (real data if present, else the synthetic release) in
several layouts, each repeated, medians printed with the time per fold and the throughput against
the first layout (one fold alone on both cores), all measured in the same invocation:

* ``1 fold, 1 worker x 2 cores``: the reference (APc, w1 = w2 = 1, user B);
* ``2 folds, 2 workers x 1 core``: two processes side by side;
* ``N folds, 1 worker x 2 cores, --stack N``: N folds in one vectorised step;
* ``N folds, 2 workers x 1 core, --stack N/2``: both.

With ``--grid-layout``, only the layout the grids use (8 folds, 2 workers x 1 core, no stack),
once per ``--loops`` value: what the LSTM's compiled loops save end to end.

    python bench/fold_time.py [--repeats 3] [--variant APc] [--hidden 128] [--epochs 30] [--stack 8]
    python bench/fold_time.py --grid-layout --loops graph xla [--fresh-workers]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from jigsaws_tools.dataset import default_data_dir

SPEC = """
preset = "quick"
data_dir = "{data}"
test_users = {folds}
hidden = {hidden}
epochs = {epochs}

[[experiments]]
variants = ["{variant}"]
"""


def data_source() -> str:
    real = default_data_dir()
    return str(real) if (real / "transcriptions").is_dir() else "synthetic"


FOLDS = ["B", "C", "D", "E", "F", "G", "H", "I"]


def run_parser(description: str) -> argparse.ArgumentParser:
    """The options every run-timing bench shares: repeats, and the run's variant, width and
    length (the quick preset's APc by default)."""
    parser = argparse.ArgumentParser(description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--variant", default="APc")
    parser.add_argument("--hidden", type=int, default=128)
    parser.add_argument("--epochs", type=int, default=30)
    return parser


#: ``multitask-grid`` with a fresh worker process for every job (as before workers were reused)
FRESH_WORKERS = ("import sys; import multitask.grid.executors as e; e.JOBS_PER_WORKER = 1; "
                 "from multitask.grid.cli import main; sys.exit(main(sys.argv[1:]))")


def timed_grid(folds: list[str], workers: int, stack: int, args: argparse.Namespace, loops: str = "graph",
               fresh: bool = False) -> float:
    """Seconds for ``multitask-grid`` to finish ``folds`` with ``workers`` workers, from scratch;
    ``fresh``: a new worker process for every job."""
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "spec.toml"
        spec.write_text(SPEC.format(data=data_source(), folds=folds, hidden=args.hidden,
                                    epochs=args.epochs, variant=args.variant))
        start = time.perf_counter()
        grid = ["-c", FRESH_WORKERS] if fresh else ["-m", "multitask.grid.cli"]
        subprocess.run([sys.executable, *grid, "--spec", str(spec),
                        "--out", str(Path(tmp) / "out"), "--workers", str(workers),
                        "--stack", str(stack), "--loops", loops], check=True,
                       capture_output=True)
        return time.perf_counter() - start


def main() -> None:
    parser = run_parser(__doc__)
    parser.add_argument("--stack", type=int, default=8, help="folds trained together (<= 8)")
    parser.add_argument("--grid-layout", action="store_true",
                        help="only 8 folds on 2 workers x 1 core, once per --loops value")
    parser.add_argument("--loops", nargs="+", default=["graph"], choices=["graph", "xla"],
                        help="with --grid-layout: the loops to time (stacks need graph loops)")
    parser.add_argument("--fresh-workers", action="store_true",
                        help="with --grid-layout: also time each with a new worker per job")
    args = parser.parse_args()
    n = args.stack
    if args.grid_layout:                                    # folds, workers, stack, loops
        layouts = [(len(FOLDS), 2, 1, loops, fresh) for loops in args.loops
                   for fresh in ((False, True) if args.fresh_workers else (False,))]
    else:
        layouts = [(1, 1, 1, "graph", False), (2, 2, 1, "graph", False),
                   (n, 1, n, "graph", False), (n, 2, n // 2, "graph", False)]
    print(f"quick preset folds: {args.variant}, H={args.hidden}, {args.epochs} epochs, data "
          f"{data_source()}; median of {args.repeats}, process start and data loading included")
    reference = None
    for folds, workers, stack, loops, fresh in layouts:
        times = [timed_grid(FOLDS[:folds], workers, stack, args, loops, fresh)
                 for _ in range(args.repeats)]
        per_fold = statistics.median(times) / folds
        reference = reference or per_fold
        print(f"{folds} fold(s), {workers} worker(s) x {2 // workers} core(s), stack {stack}, "
              f"{loops} loops{', a fresh worker per job' if fresh else ''}: "
              f"median {statistics.median(times):6.1f} s (min {min(times):.1f}, max "
              f"{max(times):.1f}) -> {per_fold:5.1f} s per fold, throughput "
              f"{reference / per_fold:.2f}x", flush=True)


if __name__ == "__main__":
    main()
