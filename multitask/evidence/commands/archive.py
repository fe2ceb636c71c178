"""``multitask-tables archive GRID DIR``: a grid's scores archive, small enough to commit.

Writes ``grid.json`` and every finished run's ``config.json``, ``metrics.json``,
``finished.json``, ``timing.json``, ``history.csv``, ``gradnorm.csv`` and
``test_predictions.json`` (its predicted labels of each test trial, compressed, never the true
ones: ``multitask.grid.kept_predictions``), and ``archive.json`` (where and when it was archived,
each fold's test trials, the time-only progress model's per-fold scores, computed from the
grid's release: ``--data-dir``, else the folder it records), without weights or the predictions
CSVs (which carry the release's labels): about 20 kB a run, and up to 5 kB of predictions. The
archive is a grid folder: ``multitask-tables paper DIR`` tabulates it with the data absent (its
example-trial figures read their true labels from the data), and ``multitask-grid`` continues it
after a copy, on any machine. DIR is a new or empty folder, or an earlier archive of the same
spec, which it replaces whole.

    multitask-tables archive runs/converged results/grid
    multitask-tables archive runs/converged results/grid --data-dir /path/to/Suturing
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import add_data_option, check_folders

SUMMARY = "a grid's scores archive: configs, scores, logs, predictions"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grid", type=Path, metavar="GRID", help="output folder of multitask-grid")
    parser.add_argument("archive", type=Path, metavar="DIR",
                        help="the archive: a new folder, or an earlier archive to replace")
    add_data_option(parser, "the time-only progress model's per-fold scores it keeps")


def run(args: argparse.Namespace) -> None:
    from ...grid.archive import archive_grid

    check_folders([args.grid], "a grid folder, a scores archive or a folder of runs")
    finished, recorded = archive_grid(args.grid, args.archive, args.data_dir)
    print(f"{args.archive}: {finished} of {recorded} runs archived (finished ones)")
