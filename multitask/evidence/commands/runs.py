"""``multitask-tables runs DIR --out OUT``: tables of runs trained one by one, without a grid.

DIR is a run folder of ``multitask-train`` or ``baseline-train``, or a folder holding such runs at
any depth (no ``grid.json``). Writes ``runs.csv`` (one row per run, with its folder),
``per_fold.csv`` (mean over seeds per configuration and fold) and ``summary.csv`` (mean and std
over folds) to ``--out``, listed in ``tables.json``; each run's configuration, seed and held-out
user come from its ``config.json``. The paper's tables, the claims and the figures pair
configurations over the folds and seeds a grid's spec guarantees: ``multitask-tables paper``.
``multitask-tables pair`` compares two configurations of these runs.

    multitask-tables runs runs/ --out runs/tables
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import add_out_options, add_seeds_option, check_folders, publish, seeds_of
from .paper import MANIFEST

SUMMARY = "tables of runs trained one by one (no grid)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folder", type=Path, metavar="DIR",
                        help="a run folder, or a folder holding run folders (no grid.json)")
    add_out_options(parser, MANIFEST)
    parser.add_argument("--allow-incomplete", action="store_true",
                        help="go on although runs are unfinished or unreadable, or one "
                             "configuration, seed and fold has two runs (the first is kept), "
                             "naming those left out (default: refuse)")
    add_seeds_option(parser)


def run(args: argparse.Namespace) -> None:
    from ..runs.standalone import is_run_collection
    from ..studies.paper import run_collection_tables

    check_folders([args.folder], "a run folder or a folder of runs")
    if not is_run_collection(args.folder):
        raise ValueError(f"{args.folder} is no run folder and holds none (a grid's tables: "
                         f"multitask-tables paper {args.folder})")
    publish(args.out, MANIFEST, args.overwrite,
            lambda staging: run_collection_tables(args.folder, staging, args.allow_incomplete,
                                                  seeds_of(args)),
            kept=("figures/",))
