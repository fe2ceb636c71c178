"""Command-line pieces shared by the commands that use a trained run: ``multitask-predict``,
``multitask-evaluate`` and ``multitask-export``. Imports no TensorFlow, so ``--help`` is quick;
each command runs its work through ``jigsaws_tools.cli.common.run_command``."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from baseline.options import add_threads_argument
from jigsaws_tools.cli.arg_types import positive_int
from jigsaws_tools.cli.common import command_parser, import_tensorflow

if TYPE_CHECKING:
    from .trained_run import TrainedRun


def trained_run_parser(prog: str, description: str | None) -> argparse.ArgumentParser:
    """The shared parser (``command_parser``: ``--version``, ``-v``) with ``RUN_DIR``,
    ``--checkpoint``, ``--overwrite`` and ``--threads``."""
    parser = command_parser(prog, description)
    parser.add_argument("run_dir", metavar="RUN_DIR", type=Path,
                        help="a run folder written by multitask-train, baseline-train or "
                             "multitask-grid (holds config.json and checkpoints/)")
    parser.add_argument("--checkpoint", metavar="N", type=positive_int, default=None,
                        help="use the weights saved after sweep N (checkpoints/ckpt-N) "
                             "(default: the latest, the final weights of a finished run)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace the outputs of an earlier command (default: refuse)")
    add_threads_argument(parser, "cores to use (0 = all)")
    return parser


def stream_layout_advice(layout: str, command: str) -> str:
    """What ``--stream``, which reads ``layout`` only, advises for recordings of another layout,
    in place of ``--format``'s advice (``run_command``'s ``layout_advice``): to run ``command``
    offline with ``--format``."""
    return (f"--stream reads {layout} only (recordings of another layout: {command} offline, "
            "without --stream, with --format FILE.toml; docs/DATA.md, 'Your own recordings')")


def load_for_command(args: argparse.Namespace, loops: str | None = None) -> TrainedRun:
    """The ``TrainedRun`` of ``RUN_DIR`` at ``--checkpoint``: TensorFlow imported quietly
    (``import_tensorflow``), then its threads set, then the weights loaded (``load_run``, its
    ``loops``)."""
    import_tensorflow()
    from rnn_seg.threads import configure_threads

    from .trained_run import load_run, read_run_config

    encoder = read_run_config(args.run_dir)[0].encoder
    configure_threads(args.threads, encoder.hidden, encoder.precision,
                      bidirectional=encoder.bidirectional)
    return load_run(args.run_dir, args.checkpoint, loops)
