"""Accuracy parity of bfloat16 products: the same runs in float32 and bfloat16, paired by fold.

Trains model A and APc (w1 = w2 = 1, revised labels, bidirectional) on every LOUO fold at the
``quick`` budget, once with ``precision = "fp32"`` and once with ``"bf16"`` (same seeds, same
everything else), as two grids under ``--out`` (resumable: finished runs are kept), plus the
forward (online) A and APc in float32, whose runs ``multitask-evaluate --stream`` scores for the
cost of streaming. Prints, per model and gesture metric, both means over folds, the mean paired
difference (bf16 - fp32) and the two-sided Wilcoxon signed-rank p-value over folds.

    python bench/bf16_parity.py --out runs/bf16_parity [--workers 2]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pandas as pd
from scipy.stats import wilcoxon

SPEC = """preset = "quick"
precision = "{precision}"

[[experiments]]
variants = ["A", "APc"]
{extra}"""
FORWARD = """
[[experiments]]
variants = ["A", "APc"]
directions = ["forward"]
"""
METRICS = ("gesture_accuracy", "gesture_edit", "gesture_f1@10")


def run_grid(out: Path, precision: str, workers: int) -> Path:
    grid = out / precision
    spec = out / f"{precision}.toml"
    out.mkdir(parents=True, exist_ok=True)
    spec.write_text(SPEC.format(precision=precision, extra=FORWARD if precision == "fp32" else ""))
    subprocess.run([sys.executable, "-m", "multitask.grid_cli", "--spec", str(spec), "--out",
                    str(grid), "--workers", str(workers)], check=True)
    return grid


def per_fold(grid: Path) -> pd.DataFrame:
    from multitask.collect import run_rows

    runs, _ = run_rows(grid)
    runs = runs[runs.direction == "bidirectional"]
    return runs.groupby(["variant", "fold"])[list(METRICS)].mean()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("runs/bf16_parity"))
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    fp32, bf16 = (per_fold(run_grid(args.out, p, args.workers)) for p in ("fp32", "bf16"))
    both = fp32.join(bf16, lsuffix="_fp32", rsuffix="_bf16", how="inner")
    print(f"{'model':6s} {'metric':18s} {'fp32':>6s} {'bf16':>6s} {'diff':>6s} {'p':>6s} folds")
    for variant, rows in both.groupby(level="variant"):
        for metric in METRICS:
            diff = rows[f"{metric}_bf16"] - rows[f"{metric}_fp32"]
            p = wilcoxon(diff).pvalue if (diff != 0).any() else 1.0
            print(f"{variant:6s} {metric:18s} {rows[f'{metric}_fp32'].mean():6.2f} "
                  f"{rows[f'{metric}_bf16'].mean():6.2f} {diff.mean():+6.2f} {p:6.3f} {len(rows)}")


if __name__ == "__main__":
    main()
