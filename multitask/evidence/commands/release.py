"""``multitask-tables release GRID --out DIR``: a grid's kept test predictions as per-split files
that any program can read and ``multitask-tables score`` scores: a reference to pair against.

One folder per configuration and seed, ``<annotations>/<direction>/<variant>-<weighting>/seed<k>/``,
with one ``<trial>.csv`` per trial of the release (the prediction of the run whose test user made
it): columns ``frame`` (every frame of the recording, from 1: 30 Hz in JIGSAWS), ``gesture``
and, for models with a progress head, ``progress``; a frame holds the prediction of the last
sample of its run's model (5 Hz: every 6th frame) at or before it. ``README.md`` says so for
readers without this project. Needs a grid or scores archive whose runs kept their predictions,
and the data (the frames): ``--data-dir``, else the folder the runs record. ``--configs`` keeps some configurations (``A-fixed``, ``original/A-fixed``).
Each run or configuration left out (unfinished, of other settings than the grid's spec, without
kept predictions) is named in a ``note:`` line on standard error.

    multitask-tables release results/reference/grid --out reference_release
    multitask-tables score reference_release/revised/bidirectional/A-fixed/seed0 --rate 30 \\
        --out a_scored
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import add_out_options, check_folders, publish_noted

SUMMARY = "a grid's test predictions as per-split files others can read"
#: The list of the files the last call wrote into ``--out``.
MANIFEST = "release.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grid", type=Path, metavar="GRID",
                        help="a grid folder or scores archive whose runs kept predictions")
    parser.add_argument("--configs", nargs="+", default=[], metavar="CONFIG",
                        help="only these configurations, e.g. A-fixed original/APoc-fixed "
                             "(default: every one)")
    parser.add_argument("--data-dir", type=Path, metavar="DIR",
                        help="the release the runs read, for the trials' frames (default: the "
                             "folder each run records)")
    add_out_options(parser, MANIFEST)


def run(args: argparse.Namespace) -> None:
    from ..studies.release import write_release

    check_folders([args.grid], "a grid folder or a scores archive")
    record = {"grid": str(args.grid), "configs": args.configs}

    def work(staging: Path) -> tuple[list[Path], list[str]]:
        released = write_release(args.grid, staging, args.configs, args.data_dir)
        record["sample_hz"] = released.sample_hz
        return released.paths, released.left_out

    publish_noted(args.out, MANIFEST, args.overwrite, work, record=record)
