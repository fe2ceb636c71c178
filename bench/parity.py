"""Accuracy parity of an execution option: the same runs with and without it, paired by fold.

Trains model A and APc (w1 = w2 = 1, revised labels, bidirectional) on every LOUO fold at the
``quick`` budget, once as the reference (float32 products, TensorFlow-op loops) and once with
the option under test (``--compare bf16``: bfloat16 products; ``--compare xla``: XLA-compiled
loops; ``--compare fused``: the fused C++ loops), same seeds and everything else, as grids under
``--out`` (resumable: finished runs are kept; the reference grid is shared by every comparison).
The reference grid also trains the forward (online) A and APc, whose runs ``multitask-evaluate
--stream`` scores for the cost of streaming. Prints, per model and gesture metric, both means over folds, the mean paired
difference (option - reference) and the two-sided Wilcoxon signed-rank p-value over folds.

    python bench/parity.py --compare bf16 --out runs/parity [--workers 2]
    python bench/parity.py --compare xla --out runs/parity
    python bench/parity.py --compare fused --out runs/parity     # the fused C++ loops (#49)
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pandas as pd
from scipy.stats import wilcoxon

SPEC = """preset = "quick"
{option}

[[experiments]]
variants = ["A", "APc"]
{extra}"""
FORWARD = """
[[experiments]]
variants = ["A", "APc"]
directions = ["forward"]
"""
#: grid name -> its spec lines; "fp32" is the reference. Every option but its own is the
#: reference's (float32, graph loops), never the default ``auto`` loops.
OPTIONS = {"fp32": 'precision = "fp32"\nloops = "graph"',
           "bf16": 'precision = "bf16"\nloops = "graph"',
           "xla": 'loops = "xla"', "fused": 'loops = "fused"'}
METRICS = ("gesture_accuracy", "gesture_edit", "gesture_f1@10")


def run_grid(out: Path, name: str, workers: int) -> Path:
    grid = out / name
    spec = out / f"{name}.toml"
    out.mkdir(parents=True, exist_ok=True)
    spec.write_text(SPEC.format(option=OPTIONS[name], extra=FORWARD if name == "fp32" else ""))
    subprocess.run([sys.executable, "-m", "multitask.grid.cli", "--spec", str(spec), "--out",
                    str(grid), "--workers", str(workers)], check=True)
    return grid


def per_fold(grid: Path) -> pd.DataFrame:
    from multitask.evidence.runs.collect import run_rows

    runs, _ = run_rows(grid)
    runs = runs[runs.direction == "bidirectional"]
    return runs.groupby(["variant", "fold"])[list(METRICS)].mean()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--compare", choices=[o for o in OPTIONS if o != "fp32"], default="bf16")
    parser.add_argument("--out", type=Path, default=Path("runs/parity"))
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    ref, new = "fp32", args.compare
    reference, option = (per_fold(run_grid(args.out, name, args.workers)) for name in (ref, new))
    both = reference.join(option, lsuffix=f"_{ref}", rsuffix=f"_{new}", how="inner")
    print(f"{'model':6s} {'metric':18s} {ref:>6s} {new:>6s} {'diff':>6s} {'p':>6s} folds")
    for variant, rows in both.groupby(level="variant"):
        for metric in METRICS:
            diff = rows[f"{metric}_{new}"] - rows[f"{metric}_{ref}"]
            p = wilcoxon(diff).pvalue if (diff != 0).any() else 1.0
            print(f"{variant:6s} {metric:18s} {rows[f'{metric}_{ref}'].mean():6.2f} "
                  f"{rows[f'{metric}_{new}'].mean():6.2f} {diff.mean():+6.2f} {p:6.3f} {len(rows)}")


if __name__ == "__main__":
    main()
