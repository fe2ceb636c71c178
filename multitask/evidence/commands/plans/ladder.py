"""``multitask-tables ladder GRID... --lengths N... --out DIR``: the convergence ladders of
``results/tcn/PLAN_factors.md`` (section E) from each backbone's pilot runs.

Each GRID holds one backbone's pilot runs, trained for the ladder's longest length at a constant
learning rate (or its scores archive). For every run and length N, the project's convergence
check (``rnn_seg.convergence``: the 95 % interval of the training loss's drop over the last
tenth) on its ``history.csv`` cut at N epochs, as if the schedule had ended there
(``ladder_runs.csv``); per configuration and length, the runs still falling, undecided and
converged (``ladder.csv``, ``ladder.md``); per backbone, among the lengths long enough to judge
every run, the shortest at which no run is still falling, else the longest
(``ladder_choice.csv``). Only training losses are read. A grid not finished or given twice, a
run whose learning rate decays (an LSTM's) is refused. Listed in ``ladder.json``
(``plans.ladder``).

    multitask-tables ladder runs/tcn/ladders/ms-tcn --lengths 50 100 150 200 \\
        --out results/tcn/ladders/ms-tcn-tables
"""
from __future__ import annotations

import argparse
from pathlib import Path

from jigsaws_tools.cli.arg_types import positive_int

from ..common import add_out_options, check_folders, publish

SUMMARY = "convergence ladders: each pilot run's loss at shorter lengths"
#: The list of the files the last call wrote into ``--out``; it names the grids too.
MANIFEST = "ladder.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grids", type=Path, nargs="+", metavar="GRID",
                        help="a backbone's grid of pilot runs (or its scores archive)")
    parser.add_argument("--lengths", type=positive_int, nargs="+", required=True, metavar="N",
                        help="the ladder's lengths in epochs, none beyond the runs' schedule")
    add_out_options(parser, MANIFEST)


def run(args: argparse.Namespace) -> None:
    from ...plans.ladder import write_ladder

    check_folders(args.grids, "a grid folder of pilot runs or its scores archive")
    publish(args.out, MANIFEST, args.overwrite,
            lambda staging: write_ladder(args.grids, args.lengths, staging),
            record={"grids": [str(p) for p in args.grids], "lengths": args.lengths})
