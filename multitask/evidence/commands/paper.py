"""``multitask-tables paper GRID``: the paper's tables, claims and figures from a grid's runs.

Writes to ``--out`` (default ``GRID/tables``), listed in ``tables.json``: ``runs.csv``,
``per_fold.csv``, ``summary.csv``; Tables I-III against the paper and the annotation ablation
(``table1|2|3``, ``ablation_annotations``: ``.csv`` and ``.tex``); the claims tested with paired
statistics (``claims.csv|.tex``, ``claims_note.tex``, ``claims_config.json``); ``per_gesture.csv``
and ``figures/`` (PNG and PDF; ``--curves`` adds the training curves). A grid of another task
gets the claims of the paper's conjecture (multi-task against A on that task) instead of the
paper's tables. The time-only progress rows and the example figures' true labels come from the
grid's release (``--data-dir``, else the folder the grid records); the rows, from a scores
archive, need no release. Missing, unfinished or unreadable runs are an error naming them, unless
``--allow-incomplete`` (marked in the tables) or ``--finished-only`` (left out).

    multitask-tables paper runs/converged --out results --curves --example-trial Suturing_D003
    multitask-tables paper results/grid --out tables --seeds 0 --no-figures
    multitask-tables paper results/grid --out tables --data-dir /path/to/Suturing
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import (add_data_option, add_out_options, add_run_options, check_folders, publish,
                     seeds_of)

SUMMARY = "the paper's Tables I-III, claims and figures from a grid"
#: The list of the files the last call wrote into ``--out`` (``rnn_seg.runs.manifest``).
MANIFEST = "tables.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grid", type=Path, metavar="GRID",
                        help="output folder of multitask-grid, or its scores archive")
    add_out_options(parser, MANIFEST, default="GRID/tables")
    parser.add_argument("--no-figures", action="store_true", help="write the tables only")
    parser.add_argument("--example-trial", metavar="TRIAL",
                        help="test trial of the example figures, e.g. Suturing_D003 (default: "
                             "the first test trial of the first fold)")
    parser.add_argument("--curves", action="store_true",
                        help="also draw training curves from every run's history.csv: per "
                             "configuration the losses and test accuracies, a line per fold")
    parser.add_argument("--ours-only", action="store_true",
                        help="LaTeX tables with our numbers alone, without the paper's columns "
                             "(the CSVs keep them)")
    add_data_option(parser, "the time-only progress rows and the example figures' true labels")
    add_run_options(parser)


def run(args: argparse.Namespace) -> None:
    from ..runs.standalone import is_run_collection
    from ..studies.paper import write_tables

    check_folders([args.grid], "a grid folder or a scores archive")
    if is_run_collection(args.grid):
        raise ValueError(f"{args.grid} holds runs trained one by one, not a grid: tabulate them "
                         f"with multitask-tables runs {args.grid} --out DIR")
    left_alone = list(_left_alone(args))     # the study adds what it cannot redraw here
    publish(args.out or args.grid / "tables", MANIFEST, args.overwrite,
            lambda staging: write_tables(
                args.grid, staging, figures=not args.no_figures, ours_only=args.ours_only,
                example_trial=args.example_trial, curves=args.curves,
                allow_incomplete=args.allow_incomplete, seeds=seeds_of(args),
                finished_only=args.finished_only, data_dir=args.data_dir,
                left_alone=left_alone),
            kept=left_alone)


def _left_alone(args: argparse.Namespace) -> tuple[str, ...]:
    """The folders of ``--out`` whose figures a call told not to draw them leaves as they are."""
    if args.no_figures:
        return ("figures/",)
    return () if args.curves else ("figures/curves/",)
