"""End-to-end time of LOUO folds at the ``quick`` preset, and the throughput of running several at once.

Runs ``multitask-grid`` on fresh folders (real data if present, else the synthetic release):

* ``1 x 2 cores``: one fold (APc, w1 = w2 = 1, user B) alone, both cores in the one run;
* ``2 x 1 core``: two folds (users B and C) at once, one single-core worker each.

Each measurement is repeated and the median printed, with the time per fold and the throughput
ratio (folds per hour, 2 x 1 against 1 x 2) measured in the same invocation.

    python bench/fold_time.py [--repeats 3] [--variant APc] [--hidden 128] [--epochs 30]
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
data = "{data}"
folds = {folds}
hidden = {hidden}
epochs = {epochs}

[[experiments]]
variants = ["{variant}"]
"""


def data_source() -> str:
    real = default_data_dir()
    return str(real) if (real / "transcriptions").is_dir() else "synthetic"


def timed_grid(folds: list[str], workers: int, args) -> float:
    """Seconds for ``multitask-grid`` to finish ``folds`` with ``workers`` workers, from scratch."""
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "spec.toml"
        spec.write_text(SPEC.format(data=data_source(), folds=folds, hidden=args.hidden,
                                    epochs=args.epochs, variant=args.variant))
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "multitask.grid_cli", "--spec", str(spec),
                        "--out", str(Path(tmp) / "out"), "--workers", str(workers)],
                       check=True, capture_output=True)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--variant", default="APc")
    parser.add_argument("--hidden", type=int, default=128)
    parser.add_argument("--epochs", type=int, default=30)
    args = parser.parse_args()
    print(f"quick preset fold: {args.variant}, H={args.hidden}, {args.epochs} epochs, data "
          f"{data_source()}; median of {args.repeats}, process start and data loading included")
    single = [timed_grid(["B"], 1, args) for _ in range(args.repeats)]
    pair = [timed_grid(["B", "C"], 2, args) for _ in range(args.repeats)]
    one, two = statistics.median(single), statistics.median(pair)
    print(f"1 fold,  1 worker x 2 cores: median {one:6.1f} s  (min {min(single):.1f}, "
          f"max {max(single):.1f})  -> {one:.1f} s per fold")
    print(f"2 folds, 2 workers x 1 core: median {two:6.1f} s  (min {min(pair):.1f}, "
          f"max {max(pair):.1f})  -> {two / 2:.1f} s per fold")
    print(f"throughput of 2 x 1 core against 1 x 2 cores: {2 * one / two:.2f}x")


if __name__ == "__main__":
    main()
