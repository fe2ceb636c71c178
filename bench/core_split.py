"""How a paper-size grid should use two cores: one run on both, or two one-core runs at once.

Trains short paper-size runs (``multitask-train``, H=1024 by default, the real release when
present, else the synthetic one) in two layouts, alternating them ``--repeats`` times in the
same invocation:

* ``1 run x 2 cores``: one process with ``--threads 2`` (the reference);
* ``2 runs x 1 core``: two processes at once, ``--threads 1`` each, on two folds.

Each process trains ``--sweeps`` sweeps and evaluates once; its ``timing.json`` gives the seconds
of its training sweeps. Prints, per layout, the median seconds per sweep of one run and the
throughput (sweeps per hour of the whole machine, i.e. summed over the runs at once), and the
throughput ratio of the second layout over the first: above 1, two one-core workers finish a
grid sooner (``multitask-grid --workers 2``); below 1, one worker on both cores does. The runs use
the engine's default LSTM loops (``auto``: fused where they build, since 2026-11-27; the
measurements of issue 45 in docs/PERFORMANCE.md were made on ``graph``, the default then).

    python bench/core_split.py [--repeats 2] [--sweeps 12] [--hidden 1024] [--variant A]
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import tempfile
from pathlib import Path

from fold_time import data_source

LAYOUTS = {"1 run x 2 cores": (("B",), 2), "2 runs x 1 core": (("B", "C"), 1)}


def train_command(args, data: str, fold: str, threads: int, out: Path) -> list[str]:
    source = ["--synthetic"] if data == "synthetic" else ["--data-dir", data]
    return ["multitask-train", *source, "--variant", args.variant, "--hidden", str(args.hidden),
            "--test-user", fold, "--sweeps", str(args.sweeps), "--eval-at", str(args.sweeps),
            "--no-plots", "--threads", str(threads), "--out", str(out)]


def seconds_per_sweep(args, data: str, folds: tuple[str, ...], threads: int) -> list[float]:
    """Start one run per fold at once; the training seconds per sweep of each."""
    with tempfile.TemporaryDirectory() as scratch:
        outs = [Path(scratch) / fold for fold in folds]
        processes = [subprocess.Popen(train_command(args, data, fold, threads, out),
                                      stdout=subprocess.DEVNULL)
                     for fold, out in zip(folds, outs)]
        for process in processes:
            if process.wait():
                raise SystemExit(f"core_split: a run failed (exit {process.returncode})")
        return [json.loads((out / "timing.json").read_text())["train"] / args.sweeps
                for out in outs]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--sweeps", type=int, default=12)
    parser.add_argument("--hidden", type=int, default=1024)
    parser.add_argument("--variant", default="A")
    args = parser.parse_args()
    data = data_source()
    print(f"data: {data}; {args.variant}, H={args.hidden}, {args.sweeps} sweeps a run")
    times: dict[str, list[float]] = {name: [] for name in LAYOUTS}
    for _ in range(args.repeats):
        for name, (folds, threads) in LAYOUTS.items():
            times[name] += seconds_per_sweep(args, data, folds, threads)
    throughput = {}
    for name, (folds, _) in LAYOUTS.items():
        median = statistics.median(times[name])
        throughput[name] = len(folds) * 3600 / median
        print(f"{name}: {median:.3f} s per sweep of a run (min {min(times[name]):.3f}, "
              f"max {max(times[name]):.3f}); {throughput[name]:.0f} sweeps per hour")
    first, second = LAYOUTS
    print(f"throughput {second} / {first}: {throughput[second] / throughput[first]:.2f}x")


if __name__ == "__main__":
    main()
