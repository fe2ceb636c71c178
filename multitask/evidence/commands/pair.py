"""``multitask-tables pair GRID X Y --metric M``: is configuration X better than Y, and by how
much? The paired statistics of ``X - Y`` over the LOUO folds, printed.

Per fold each side is the mean over its seeds; the exact sign-flip test over the folds, its 95 %
interval, and the seed and fold shares of the variance (``statistics.paired``, the procedure of
``claims.csv``). A configuration is ``[annotations/][direction/]<variant>-<weighting>``, as in
the grid's run folders (``APoc-gradnorm``, ``original/A-fixed``, ``forward/APc-fixed``);
``--minus X2 Y2`` makes it a difference of differences, ``(X - Y) - (X2 - Y2)``. GRID may be a
folder of runs trained one by one too (``multitask-tables runs``).

    multitask-tables pair runs/converged APc-fixed A-fixed --metric gesture_edit
    multitask-tables pair results/grid APr-gradnorm APr-fixed --minus APc-gradnorm APc-fixed \\
        --metric gesture_accuracy
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import add_run_options, check_folders, seeds_of

SUMMARY = "the paired statistics of one comparison, X - Y, printed"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grid", type=Path, metavar="GRID",
                        help="a grid folder, a scores archive or a folder of runs")
    parser.add_argument("x", metavar="X", help="a configuration, e.g. APc-fixed")
    parser.add_argument("y", metavar="Y", help="the configuration it is compared with, "
                                               "e.g. A-fixed")
    parser.add_argument("--metric", required=True,
                        help="a metric column of runs.csv, e.g. gesture_edit (required)")
    parser.add_argument("--minus", nargs=2, metavar=("X2", "Y2"),
                        help="(X - Y) - (X2 - Y2), paired per fold (default: X - Y alone)")
    add_run_options(parser)


def run(args: argparse.Namespace) -> None:
    from ..statistics.paired import ConfigId, Contrast, NotPaired, config_labels, paired
    from ..studies.paper import read_runs

    check_folders([args.grid], "a grid folder, a scores archive or a folder of runs")
    contrast = Contrast(ConfigId.parse(args.x), ConfigId.parse(args.y),
                        tuple(map(ConfigId.parse, args.minus)) if args.minus else None)
    runs, _ = read_runs(args.grid, args.allow_incomplete, seeds_of(args), args.finished_only)
    try:
        print(paired(runs, contrast, args.metric).describe())
    except NotPaired as error:
        raise NotPaired(f"{error}; {args.grid} holds {', '.join(config_labels(runs))}") from None
