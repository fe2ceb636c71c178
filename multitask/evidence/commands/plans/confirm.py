"""``multitask-tables confirm PLAN --out DIR``: a pre-registered confirmatory analysis, run
exactly as its plan file says.

The plan (TOML, ``results/confirm/plan.toml``) names its grids, seeds, endpoints, families and
decision rules; a part whose grid has not finished every run of its seeds is not analysed (no
interim looks). The exploratory analyses the plan's text names, in an ``exploratory.toml``
beside the plan file, go to ``exploratory.csv``, never into the plan's rows. Writes
``confirm.csv``, ``confirm_per_fold.csv`` and ``confirm.md`` (the outcome in the plan's words)
to ``--out``, listed in ``confirm.json`` (``plans.confirm``, ``plans.confirm_report``).

    multitask-tables confirm results/confirm/plan.toml --out results/confirm
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..common import add_out_options, publish

SUMMARY = "a pre-registered confirmatory analysis, as its plan file says"
#: The list of the files the last call wrote into ``--out``.
MANIFEST = "confirm.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("plan", type=Path, metavar="PLAN",
                        help="the plan file (TOML), e.g. results/confirm/plan.toml; it names "
                             "its grids")
    add_out_options(parser, MANIFEST)


def run(args: argparse.Namespace) -> None:
    """The plan's analysis into ``--out``, all files or none; the plan and its exploratory file
    are checked before ``--out``'s lock is taken."""
    from ...plans.confirm import read_plan
    from ...plans.confirm_report import write_confirmatory
    from ...plans.exploratory import EXPLORATORY_FILE, read_exploratory

    read_exploratory(args.plan.parent / EXPLORATORY_FILE, read_plan(args.plan))

    def write(staging: Path) -> list[Path]:
        written, skipped = write_confirmatory(args.plan, staging)
        for line in skipped:
            print(f"note: {line}", file=sys.stderr)
        return written

    publish(args.out, MANIFEST, args.overwrite, write)
