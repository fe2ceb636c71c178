"""``multitask-tables design PLAN --out DIR``: what a confirmatory plan's design could detect,
and whether more seeds or more folds would change it (exploratory).

For each primary endpoint of the plan's parts: the seed and fold shares of the variance of its
per-fold differences, with their 95 % intervals, and the exact sign-flip test's power at the
paper's gain, alone and under the plan's Holm correction, for 1 to 10 seeds and without bound
(the ceiling), at the runs' folds and at more. Writes ``design.csv`` and ``design_power.csv`` to
``--out``, listed in ``design.json`` (``plans.design``; the methods: ``statistics.design``).
``--part P --grid GRID`` reads part P's endpoints on another grid's runs (its width unchecked).

    multitask-tables design results/confirm/plan.toml --out results/confirm/design
    multitask-tables design results/confirm/plan.toml --part paper-width --grid results/grid \\
        --seeds 0 1 2 --out results/confirm/design-128
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..common import add_out_options, add_seeds_option, check_folders, publish, seeds_of

SUMMARY = "what a plan's folds x seeds could detect: variance, power"
#: The list of the files the last call wrote into ``--out``.
MANIFEST = "design.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("plan", type=Path, metavar="PLAN",
                        help="the plan file (TOML), e.g. results/confirm/plan.toml")
    parser.add_argument("--part", metavar="NAME",
                        help="only this part of the plan, e.g. paper-width (default: every "
                             "part whose grid is complete)")
    parser.add_argument("--grid", type=Path, metavar="GRID",
                        help="the part's endpoints on this grid's runs instead of its own "
                             "(needs --part; default: the plan's grid)")
    add_seeds_option(parser)
    add_out_options(parser, MANIFEST)


def run(args: argparse.Namespace) -> None:
    from ...plans.design import write_design

    if args.grid is not None:
        check_folders([args.grid], "a grid folder or a scores archive")

    def write(staging: Path) -> list[Path]:
        written, skipped = write_design(args.plan, staging, args.part, args.grid,
                                        seeds_of(args))
        for line in skipped:
            print(f"note: {line}", file=sys.stderr)
        return written

    record = {"plan": str(args.plan)} | ({"part": args.part} if args.part else {}) | (
        {"grid": str(args.grid)} if args.grid else {}) | (
        {"seeds": list(args.seeds)} if args.seeds else {})
    publish(args.out, MANIFEST, args.overwrite, write, record=record)
