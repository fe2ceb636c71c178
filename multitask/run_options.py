"""Command-line pieces shared by the commands that use a trained run: ``multitask-predict``,
``multitask-evaluate`` and ``multitask-export``. Imports no TensorFlow, so ``--help`` is quick."""
from __future__ import annotations

import argparse
import logging
import os
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from jigsaws_tools.errors import JigsawsError

if TYPE_CHECKING:
    from .trained_run import TrainedRun

DISTRIBUTION = "mtrnn-jigsaws"


def package_version() -> str:
    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return "unknown (not installed)"


def trained_run_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """A parser with ``RUN_DIR``, ``--checkpoint``, ``--overwrite`` and ``--version``."""
    parser = argparse.ArgumentParser(prog=prog, description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", metavar="RUN_DIR", type=Path,
                        help="a run folder written by multitask-train, baseline-train or "
                             "multitask-grid (holds config.json and checkpoints/)")
    parser.add_argument("--checkpoint", metavar="N", type=int, default=None,
                        help="use the weights saved after sweep N (checkpoints/ckpt-N) "
                             "(default: the latest, the final weights of a finished run)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace the outputs of an earlier command (default: refuse)")
    parser.add_argument("--threads", type=int, default=0,
                        help="cores to use, split between TensorFlow's thread pools as "
                             "rnn_seg.threads measures best (default: 0 = all)")
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    return parser


def load_for_command(args: argparse.Namespace) -> TrainedRun:
    """The ``TrainedRun`` of ``RUN_DIR`` at ``--checkpoint``, TensorFlow's threads set first."""
    from rnn_seg.threads import configure_threads

    from .trained_run import load_run, read_run_config

    encoder = read_run_config(args.run_dir)[0].encoder
    configure_threads(args.threads, encoder.hidden, encoder.precision)
    return load_run(args.run_dir, args.checkpoint)


def run_command(prog: str, body: Callable[[argparse.Namespace], None],
                args: argparse.Namespace) -> int:
    """Run a command's body with the project's error convention.

    Args:
        prog: the command's name, prefixed to messages.
        body: does the work.
        args: the parsed command line, passed to ``body``.

    Returns:
        The exit status: 0; 2 after a known error (``prog: error: ...``, no traceback); 130 when
        interrupted.
    """
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    logging.basicConfig(format=f"{prog}: %(levelname)s: %(message)s", level=logging.WARNING)
    try:
        body(args)
    except (JigsawsError, ValueError, OSError) as error:
        print(f"{prog}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    return 0
