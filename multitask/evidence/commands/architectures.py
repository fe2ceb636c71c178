"""``multitask-tables architectures GRID ... --out DIR``: the LSTM at each width, ED-TCN and
MS-TCN side by side, one grid (or scores archive) each.

Which architecture a grid holds is read from its runs (``lstm-<units>``, ``ed-tcn``,
``ms-tcn``); each grid's runs are pooled as in its own tables, never with another grid's. Writes
to ``--out``, listed in ``architectures.json``: ``architectures.csv|.tex|.md`` (A, APc and APoc
per architecture, the time-only progress row, the cost per run), the claims "progress heads help
TCN backbones" (``claims.csv|.tex``, ``claims_note.tex``, ``claims_config.json``) and Table II
with our measured rows (``table2.csv|.tex``) (``studies.architectures``).

    multitask-tables architectures results/grid results/paper/grid results/tcn/ed-tcn \\
        results/tcn/ms-tcn --out results/tcn
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import add_data_option, add_out_options, check_folders, publish

SUMMARY = "LSTM widths, ED-TCN and MS-TCN side by side, one grid each"
#: The list of the files the last call wrote into ``--out``.
MANIFEST = "architectures.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grids", type=Path, nargs="+", metavar="GRID",
                        help="one grid folder or scores archive per architecture")
    add_out_options(parser, MANIFEST)
    add_data_option(parser, "the time-only progress row (the first grid's)")


def run(args: argparse.Namespace) -> None:
    from ..studies.architectures import write_architectures

    check_folders(args.grids, "a grid's scores archive, e.g. results/tcn/ed-tcn")
    publish(args.out, MANIFEST, args.overwrite,
            lambda staging: write_architectures(args.grids, staging, args.data_dir))
