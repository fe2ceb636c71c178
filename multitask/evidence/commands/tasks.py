"""``multitask-tables tasks TASK=TABLES ... --out DIR``: the JIGSAWS tasks side by side.

Reads the tables ``multitask-tables paper`` wrote for each task (``summary.csv``,
``claims.csv``): model A's gesture scores, and each multi-task model minus A with its 95 %
interval and verdict. Nothing is recomputed, so the summary agrees with each task's own tables.
Writes ``tasks.csv`` (one row per task, model and score) and ``tasks.md`` (the table of
``results/tasks/README.md``) to ``--out``, listed in ``tasks.json`` (``studies.tasks``).

    multitask-tables tasks Suturing=results Knot_Tying=results/tasks/Knot_Tying \\
        Needle_Passing=results/tasks/Needle_Passing --out results/tasks
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import add_out_options, publish

SUMMARY = "the JIGSAWS tasks side by side, from each task's tables"
#: The list of the files the last call wrote into ``--out``.
MANIFEST = "tasks.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("tasks", nargs="+", metavar="TASK=TABLES", type=_task_tables,
                        help="a task's name and the folder of its tables, e.g. "
                             "Knot_Tying=results/tasks/Knot_Tying")
    add_out_options(parser, MANIFEST)


def _task_tables(text: str) -> tuple[str, Path]:
    task, sep, tables = text.partition("=")
    if not sep or not task or not tables:
        raise argparse.ArgumentTypeError(f"expected TASK=TABLES, got {text!r}")
    return task, Path(tables)


def run(args: argparse.Namespace) -> None:
    from ..studies.tasks import write_tasks

    publish(args.out, MANIFEST, args.overwrite,
            lambda staging: write_tasks(dict(args.tasks), staging))
