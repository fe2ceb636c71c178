"""``multitask-export``: write a trained run as a TensorFlow SavedModel.

The SavedModel loads with ``tf.saved_model.load(DIR)`` alone, without this package. Its
``serving_default`` signature takes one recording's raw kinematics in the recording format the run
trained on ([n_frames, 76] float64, JIGSAWS columns at 30 Hz, for a run trained on the release;
[n_frames, C] at the format's rate, in the columns model.json lists, for one trained on your own
recordings), preprocesses them as the run did and returns per-frame predictions equal to
multitask-predict's; ``features`` takes preprocessed 5 Hz samples. DIR/assets.extra/model.json
documents both, the recording format, the class names and the preprocessing (docs/COMMANDS.md,
"Using a trained model").
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jigsaws_tools.cli.common import run_command

from .options import load_for_command, trained_run_parser
from .output_folders import check_export_folder
from .run_record import read_run_config

PROG = "multitask-export"


def build_parser() -> argparse.ArgumentParser:
    parser = trained_run_parser(PROG, __doc__)
    parser.add_argument("--out", type=Path, required=True,
                        help="SavedModel folder to create (required; written whole at the end)")
    return parser


def _export(args: argparse.Namespace) -> None:
    read_run_config(args.run_dir)               # the run and the output folder before TensorFlow
    check_export_folder(args.out, args.overwrite)
    run = load_for_command(args, loops="graph")   # a SavedModel's; imports TensorFlow quietly:
                                                  # before any module using it
    from .export import export_run

    export_run(run, args.out, args.overwrite)
    print(f"done: {run.variant} ({args.run_dir}, checkpoint after sweep {run.checkpoint}) "
          f"exported to {args.out}; signatures serving_default(kinematics), features(features)")


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return run_command(PROG, args.verbose, lambda: _export(args), argv=argv)


if __name__ == "__main__":
    sys.exit(main())
