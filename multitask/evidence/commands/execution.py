"""``multitask-tables execution GRID --reference REF --margin POINTS --out DIR``: does an
execution path (the fused loops, bfloat16) change what a grid says?

GRID, every run finished, repeats configurations of the reference grid REF on another path, all
else equal. Per configuration and score, GRID minus REF paired by fold, *equivalent*,
*different* or *inconclusive* against the margin, and whether each model's comparison with A
reads the same: ``execution.csv``, ``execution_contrasts.csv`` and ``execution_per_fold.csv``
in ``--out``, listed in ``execution.json`` with the two grids and the margin
(``studies.execution``).

    multitask-tables execution results/precision/bf16 --reference results/grid --margin 2.0 \\
        --out results/precision/bf16-vs-fp32
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import add_out_options, check_folders, publish_noted

SUMMARY = "an execution path (fused loops, bf16) against its reference"
#: The list of the files the last call wrote into ``--out``; it names the two grids and the
#: margin too.
MANIFEST = "execution.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grid", type=Path, metavar="GRID",
                        help="the grid (or scores archive) run on the path compared")
    parser.add_argument("--reference", type=Path, metavar="REF", required=True,
                        help="the grid it repeats, on the reference path (required)")
    parser.add_argument("--margin", type=float, metavar="POINTS", required=True,
                        help="the equivalence margin in percentage points, e.g. 2.0 (required)")
    add_out_options(parser, MANIFEST)


def run(args: argparse.Namespace) -> None:
    from ..studies.execution import write_execution

    check_folders([args.grid, args.reference],
                  "a grid folder, a scores archive or a folder of runs")
    publish_noted(args.out, MANIFEST, args.overwrite,
                  lambda staging: write_execution(args.grid, args.reference, args.margin,
                                                  staging),
                  record={"option": str(args.grid), "reference": str(args.reference),
                          "margin": args.margin})
