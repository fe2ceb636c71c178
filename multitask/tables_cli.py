"""``multitask-tables GRID_DIR``: the paper's tables (CSV + LaTeX) and figures from a grid's runs.

Writes to ``--out`` (default ``GRID_DIR/tables``): ``runs.csv`` (one row per finished run),
``per_fold.csv`` (mean over seeds per configuration and fold), ``summary.csv`` (mean and std over
folds), ``table1|2|3.csv/.tex`` (ours against the paper), ``ablation_annotations.csv/.tex``
(revised against original labels), ``claims.csv/.tex`` (the paper's claims tested with paired
statistics over folds and seeds, settings in ``claims_config.json``) and ``figures/*.png|pdf``.
Unfinished runs are left out and listed. The paper's tables, the annotation ablation and its
claims are Suturing's: a grid of another task gets instead the claims of the paper's conjecture
(multi-task against model A on that task, ``claims.CONJECTURE_CLAIMS``).

A grid with missing or unfinished runs, NaN metrics, unreadable metrics or stray folders is an
error naming them (``multitask.collect``); with ``--allow-incomplete`` they are listed, and the
configurations concerned are marked incomplete in the tables (``runs``, ``runs_expected`` and
``complete`` columns of summary.csv; "(incomplete: n/m runs)" after the model's name).

``--compare X Y --metric M`` prints the paired statistics of one comparison instead, e.g.
``multitask-tables GRID --compare APc-fixed A-fixed --metric gesture_edit``; a configuration is
``[annotations/][direction/]<variant>-<weighting>`` as in the grid's run folders
(``original/APoc-gradnorm``, ``forward/A-fixed``), and ``--minus X2 Y2`` makes it a difference of
differences, ``(X - Y) - (X2 - Y2)``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from rnn_seg.rundir import RunFolderError, write_atomic

from jigsaws_tools.task_definition import PAPER_TASK

from .claims import CONJECTURE_CLAIMS
from .claims_table import write_claims
from .collect import (CONFIG_COLUMNS, METRICS, completeness, expected_runs, grid_task_name,
                      per_fold, recorded_runs, run_rows, summary)
from .figures import all_figures
from .paired import ConfigId, Contrast, NotPaired, config_labels, paired
from .tables import PAPER_TABLES, annotation_ablation, paper_best, paper_comparison, to_latex


def write_tables(grid_dir: Path, out: Path, figures: bool = True,
                 allow_incomplete: bool = False) -> list[Path]:
    """Everything ``multitask-tables`` writes; returns the paths. ``allow_incomplete``: mark
    configurations with missing runs instead of refusing (``collect.run_rows``)."""
    runs, problems = run_rows(grid_dir, allow_incomplete)
    for problem in problems:
        print(f"incomplete: {problem}", file=sys.stderr)
    folds = per_fold(runs)
    expected = expected_runs(grid_dir, recorded_runs(Path(grid_dir))[0])
    stats = summary(folds).merge(completeness(runs, expected), on=CONFIG_COLUMNS, how="left")
    written = [_csv(runs, out / "runs.csv"), _csv(folds, out / "per_fold.csv"),
               _csv(stats, out / "summary.csv")]
    if grid_task_name(grid_dir) == PAPER_TASK:
        written += _paper_tables(stats, out)
        written += write_claims(runs, out)
    else:
        written += write_claims(runs, out, claims=CONJECTURE_CLAIMS)
    if figures:
        written += all_figures(Path(grid_dir), stats, folds, out / "figures")
    return written


def _paper_tables(stats: pd.DataFrame, out: Path) -> list[Path]:
    """Tables I-III against the paper and the annotation ablation (Suturing grids only)."""
    written = []
    for table in PAPER_TABLES:
        frame = paper_comparison(stats, table)
        if frame.empty:
            continue
        written.append(_csv(frame, out / f"{table.name}.csv"))
        written.append(_tex(to_latex(frame, table.caption, table.name, ("Ours", "Paper"),
                                     paper_best(table)), out / f"{table.name}.tex"))
    ablation = annotation_ablation(stats)
    if not ablation.empty:
        caption = ("Annotation-version ablation: revised against original labels, mean (std) "
                   "over folds; Delta = revised - original.")
        written.append(_csv(ablation, out / "ablation_annotations.csv"))
        written.append(_tex(to_latex(ablation, caption, "ablation_annotations",
                                     ("Revised", "Original")), out / "ablation_annotations.tex"))
    return written


def _compare(grid_dir: Path, compare: list[str], minus: list[str] | None, metric: str,
             allow_incomplete: bool) -> str:
    """The paired statistics of one comparison, as text."""
    x, y = map(ConfigId.parse, compare)
    contrast = Contrast(x, y, tuple(map(ConfigId.parse, minus)) if minus else None)
    runs, _ = run_rows(grid_dir, allow_incomplete)
    try:
        return paired(runs, contrast, metric).describe()
    except NotPaired as error:
        raise NotPaired(f"{error}; {grid_dir} holds {', '.join(config_labels(runs))}") from None


def _csv(frame, path: Path) -> Path:
    write_atomic(path, frame.to_csv(index=False, float_format="%.4f"))
    return path


def _tex(text: str, path: Path) -> Path:
    write_atomic(path, text)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="multitask-tables", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("grid_dir", type=Path, help="output folder of multitask-grid")
    parser.add_argument("--out", type=Path, help="where to write (default GRID_DIR/tables)")
    parser.add_argument("--no-figures", action="store_true")
    parser.add_argument("--compare", nargs=2, metavar=("X", "Y"),
                        help="print the paired statistics of X - Y instead of writing tables")
    parser.add_argument("--minus", nargs=2, metavar=("X2", "Y2"),
                        help="with --compare: (X - Y) - (X2 - Y2), paired per fold")
    parser.add_argument("--metric", help=f"with --compare: {', '.join(METRICS)}, ...")
    parser.add_argument("--allow-incomplete", action="store_true",
                        help="write tables although runs are missing, unfinished or unreadable, "
                             "marking the configurations concerned incomplete")
    args = parser.parse_args(argv)
    if bool(args.compare) != bool(args.metric) or (args.minus and not args.compare):
        parser.error("--compare needs --metric, and --metric and --minus need --compare")
    try:
        if args.compare:
            print(_compare(args.grid_dir, args.compare, args.minus, args.metric,
                           args.allow_incomplete))
            return 0
        paths = write_tables(args.grid_dir, args.out or args.grid_dir / "tables",
                             figures=not args.no_figures, allow_incomplete=args.allow_incomplete)
    except (ValueError, OSError, RunFolderError) as error:
        print(f"multitask-tables: error: {error}", file=sys.stderr)
        return 2
    for path in paths:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
