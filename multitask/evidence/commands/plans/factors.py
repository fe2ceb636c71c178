"""``multitask-tables factors BASELINE LEVEL... --out DIR``: the factor study of
``results/tcn/PLAN_factors.md`` from its grids of inner runs (validation users only).

BASELINE and each LEVEL are grids whose spec sets ``inner_validation``, a level's spec differing
from the baseline's in the plan's factor keys only (and the schedule's length, ``epochs``,
factor S), and in its outer folds or a smaller ``inner_validation``: a level with fewer
validation users is set against the baseline's runs of the same users. Per level, its mean
validation score minus the baseline's per metric and for the mean of accuracy, edit and F1@10,
the per-fold differences and the folds favouring it (``factors.csv``, ``factors_per_fold.csv``);
per outer fold, the eligible levels, each factor's level taken and their combination
(``factors_choice.csv``, ``factors_settings.csv``); and, for each combination not yet run, the
spec that runs it (``combination-<folds>.toml``): run it with ``multitask-grid``, then give its
grid with ``--combination`` to settle each fold's setting; once every fold's is settled, the
settings as a grid spec's ``fold_settings`` tables (``fold_settings.toml``). Listed in
``factors.json`` (``plans.factors``).

    multitask-tables factors runs/tcn/factors/baseline runs/tcn/factors/T-5hz-k15 \\
        runs/tcn/factors/L-off --out results/tcn/factors/tables
    multitask-tables factors runs/tcn/factors/baseline runs/tcn/factors/[TLNFPH]-* \\
        --combination runs/tcn/factors/combination-B-C --out results/tcn/factors/tables
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..common import add_out_options, check_folders, publish_noted

SUMMARY = "factor study: each level vs. the baseline, each fold's choice"
#: The list of the files the last call wrote into ``--out``; it names the grids too.
MANIFEST = "factors.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("baseline", type=Path, metavar="BASELINE",
                        help="the baseline's grid of inner runs (or its scores archive)")
    parser.add_argument("levels", type=Path, nargs="+", metavar="LEVEL",
                        help="each level's grid of inner runs, named by its folder")
    parser.add_argument("--combination", type=Path, action="append", default=[],
                        metavar="GRID", help="a grid of a combination the study asked for "
                                             "(repeatable; default: none run yet)")
    add_out_options(parser, MANIFEST)


def run(args: argparse.Namespace) -> None:
    from ...plans.factors import write_factors

    check_folders([args.baseline, *args.levels, *args.combination],
                  "a grid folder of inner runs or its scores archive")
    publish_noted(args.out, MANIFEST, args.overwrite,
                  lambda staging: write_factors(args.baseline, args.levels, args.combination,
                                                staging),
                  record={"baseline": str(args.baseline), "levels": [str(p) for p in args.levels],
                          "combinations": [str(p) for p in args.combination]})
