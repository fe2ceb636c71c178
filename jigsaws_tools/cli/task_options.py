"""The ``--task`` / ``--task-file`` command-line options every command shares."""
from __future__ import annotations

import argparse

from ..task_definition import PAPER_TASK, TaskDefinition, builtin_task_names, load_task


def add_task_options(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add the mutually exclusive ``--task NAME`` and ``--task-file PATH`` to ``parser``."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--task", choices=builtin_task_names(), default=None,
                       help=f"a built-in JIGSAWS task (default: {PAPER_TASK}, the paper's)")
    group.add_argument("--task-file", metavar="PATH",
                       help="your own task definition (TOML; format in "
                            "jigsaws_tools/task_definition.py; default: none, --task's)")


def task_from_options(args: argparse.Namespace) -> TaskDefinition:
    """The task chosen by ``--task`` / ``--task-file`` (default: the paper's Suturing)."""
    return load_task(args.task_file or args.task or PAPER_TASK)
