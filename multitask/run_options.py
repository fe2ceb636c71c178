"""Command-line pieces shared by the commands that use a trained run: ``multitask-predict``,
``multitask-evaluate`` and ``multitask-export``. Imports no TensorFlow, so ``--help`` is quick."""
from __future__ import annotations

import argparse
import logging
import os
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Callable

from jigsaws_tools.errors import JigsawsError

DISTRIBUTION = "mtrnn-jigsaws"


def package_version() -> str:
    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return "unknown (not installed)"


def trained_run_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """A parser with ``RUN_DIR``, ``--checkpoint`` and ``--version``."""
    parser = argparse.ArgumentParser(prog=prog, description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", metavar="RUN_DIR", type=Path,
                        help="a run folder written by multitask-train, baseline-train or "
                             "multitask-grid (holds config.json and checkpoints/)")
    parser.add_argument("--checkpoint", metavar="N", type=int, default=None,
                        help="use the weights saved after sweep N (checkpoints/ckpt-N) "
                             "(default: the latest, the final weights of a finished run)")
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    return parser


def run_command(prog: str, body: Callable[[argparse.Namespace], None],
                args: argparse.Namespace) -> int:
    """Run ``body(args)``; a known error ends as ``prog: error: ...`` with exit status 2 and no
    traceback, an interruption with one line and status 130."""
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
