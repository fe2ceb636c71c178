"""``multitask-tables width GRID GRID ... --out DIR``: model A against APoc (GradNorm) across
LSTM widths, one grid (or scores archive) per width.

Each grid's runs say its width. The grids of one width join by ``+`` into one entry
(``results/width/h512-a180+results/confirm/h512``): each is checked as a grid on its own, then
their runs are pooled, refused unless they agree on every setting (the schedule too) and hold no
seed twice. Writes ``width.csv`` (per width and score: A, APoc and APoc - A paired over folds,
with its 95 % interval and Holm's correction over the widths) and ``width.png/.pdf`` to
``--out``, listed in ``width.json``; ``--seeds`` restricts every grid to those seeds
(``studies.width``).

    multitask-tables width results/grid results/width/h256 results/width/h512 results/paper/grid \\
        --out results/width
"""
from __future__ import annotations

import argparse

from .common import add_out_options, add_seeds_option, check_folders, publish, seeds_of

SUMMARY = "model A against APoc across LSTM widths, one grid per width"
#: The list of the files the last call wrote into ``--out``; it may share a folder with tables.
MANIFEST = "width.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("entries", nargs="+", metavar="GRID[+GRID...]",
                        help="one entry per width (two or more): a grid folder or scores "
                             "archive, or the grids of one width joined by +, their runs pooled")
    add_out_options(parser, MANIFEST)
    add_seeds_option(parser)


def run(args: argparse.Namespace) -> None:
    from ..studies.width import width_entry, write_width

    if len(args.entries) < 2:
        raise ValueError("the width study compares widths: give two entries or more, one per "
                         f"width (got {args.entries[0]})")
    entries = [width_entry(entry) for entry in args.entries]
    check_folders([grid for entry in entries for grid in entry],
                  "a grid folder, a scores archive or a folder of runs")
    publish(args.out, MANIFEST, args.overwrite,
            lambda staging: write_width(entries, staging, seeds_of(args)))
