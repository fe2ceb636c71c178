"""``multitask-tables archive GRID DIR``: a grid's scores archive, small enough to commit.

Writes ``grid.json`` and every finished run's ``config.json``, ``metrics.json``,
``finished.json``, ``timing.json``, ``history.csv`` and ``gradnorm.csv``, and ``archive.json``
(where and when it was archived, each fold's test trials), without weights or predictions (which
carry the release's labels): about 20 kB a run. The archive is a grid folder: ``multitask-tables
paper DIR`` tabulates it (without the example-trial figures, which need predictions), and
``multitask-grid`` continues it after a copy, on any machine. DIR is a new or empty folder, or an
earlier archive of the same spec, which it replaces whole.

    multitask-tables archive runs/converged results/grid
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import check_folders

SUMMARY = "a grid's scores archive (configs, metrics, logs), to commit"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grid", type=Path, metavar="GRID", help="output folder of multitask-grid")
    parser.add_argument("archive", type=Path, metavar="DIR",
                        help="the archive: a new folder, or an earlier archive to replace")


def run(args: argparse.Namespace) -> None:
    from ...grid.archive import archive_grid

    check_folders([args.grid], "a grid folder, a scores archive or a folder of runs")
    finished, recorded = archive_grid(args.grid, args.archive)
    print(f"{args.archive}: {finished} of {recorded} runs archived (finished ones)")
