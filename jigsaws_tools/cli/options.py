"""Command-line options that choose a release and its labels, shared by every command.

``--data-dir DIR`` (or ``--synthetic``, with ``--synthetic-seed``) names the release folder,
``--task`` / ``--task-file`` its task and ``--annotations`` the label version, in
``jigsaws-tools`` and every training command alike; the grid spec's key for the folder is
``data_dir`` too.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..annotations import ANNOTATION_VERSIONS
from .arg_types import non_negative_int
from ..dataset import DataConfig, default_cache_dir, default_data_dir
from ..synth import SynthConfig, ensure_release
from ..task_definition import TaskDefinition
from .task_options import add_task_options, task_from_options

#: How the default release folder is shown (``default_data_dir`` resolves it).
DEFAULT_DATA_DIR_TEXT = "$JIGSAWS_DIR, else ../shared/jigsaws/<task> next to the project"


def add_data_arguments(parser: argparse.ArgumentParser) -> argparse._ArgumentGroup:
    """``--data-dir`` | ``--synthetic``, ``--synthetic-seed``, ``--task`` | ``--task-file`` and
    ``--annotations``, in a group ``data`` that is returned for the caller's own data options."""
    data = parser.add_argument_group("data")
    source = data.add_mutually_exclusive_group()
    source.add_argument("--data-dir", type=Path, metavar="DIR",
                        help=f"JIGSAWS release folder of the task (default: "
                             f"{DEFAULT_DATA_DIR_TEXT})")
    source.add_argument("--synthetic", action="store_true",
                        help="use the embedded synthetic release instead (written once to the "
                             "cache, $JIGSAWS_CACHE_DIR or ~/.cache/mtrnn-jigsaws)")
    add_synthetic_seed_argument(data)
    add_task_options(data)
    data.add_argument("--annotations", choices=ANNOTATION_VERSIONS,
                      default=DataConfig.annotations,
                      help="labels: the release's (original) or with the paper's 12 amendments "
                           "(revised)")
    return data


def add_synthetic_seed_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup
                                ) -> argparse.Action:
    """``--synthetic-seed N``: which synthetic release (each seed is another, fixed release)."""
    return parser.add_argument("--synthetic-seed", type=non_negative_int, default=SynthConfig.seed,
                               metavar="N", help="seed of the synthetic release")


def data_dir_from_args(args: argparse.Namespace, task: TaskDefinition | None = None) -> Path:
    """The release folder of ``task`` (default: the options' ``task_from_options``) the options
    name: the synthetic release (written on first use), the ``--data-dir`` folder, or the
    default one."""
    task = task or task_from_options(args)
    if args.synthetic:
        return ensure_release(default_cache_dir(), SynthConfig(seed=args.synthetic_seed), task)
    return args.data_dir or default_data_dir(task.name)
