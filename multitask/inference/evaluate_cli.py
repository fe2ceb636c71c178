"""``multitask-evaluate``: score a trained run's saved weights on labelled trials.

Writes what a training evaluation point writes (predictions/NAME.csv, plots/NAME.png,
metrics.json) for the held-out user's trials (or --test-user's). On a run's final checkpoint it
reproduces the run's last evaluation point exactly (to float32 rounding if it trained with
--loops xla, or on the fused loops where they cannot be built here: a loaded run then runs the
op loops). --data-dir with --format scores labelled
recordings of another layout (your own robot's, at its rate). --stream scores a forward model as
it would run online (causal preprocessing of every frame; docs/REPRODUCTION.md, "Streaming").
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jigsaws_tools.cli.common import run_command
from jigsaws_tools.cli.format_options import add_format_option

from .options import load_for_command, stream_layout_advice, trained_run_parser
from .output_folders import check_evaluation_folder
from .run_record import data_folder, read_run_config

PROG = "multitask-evaluate"


def build_parser() -> argparse.ArgumentParser:
    parser = trained_run_parser(PROG, __doc__)
    parser.add_argument("--data-dir", type=Path, default=None,
                        help="the release folder of the run's task (e.g. JIGSAWS Suturing) whose "
                             "trials are scored (default: the run's data folder, as recorded in "
                             "its config.json)")
    parser.add_argument("--test-user", default=None,
                        help="user whose trials are scored (default: the user the run held out)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default: RUN_DIR/evaluate/ckpt-N_USER[_stream])")
    parser.add_argument("--stream", action="store_true",
                        help="forward models only: causal (streaming) preprocessing instead of "
                             "the offline one (default: offline, as training evaluated)")
    parser.add_argument("--no-plots", action="store_true",
                        help="skip the per-trial plots (default: draw them)")
    add_format_option(parser, "the --data-dir release's recordings (default: the format the run "
                              "trained on)")
    return parser


def _evaluate(args: argparse.Namespace) -> None:
    _check_arguments(args)
    run = load_for_command(args)                 # imports TensorFlow quietly, first
    from rnn_seg.trainer import metrics_summary

    from .evaluation import default_evaluation_dir, evaluate_run

    user = args.test_user or run.config.test_user
    out = args.out or default_evaluation_dir(run, user, args.stream)
    metrics = evaluate_run(run, out, args.data_dir, user, args.stream, not args.no_plots,
                           args.overwrite, args.format)
    print(f"{args.run_dir}, checkpoint after sweep {run.checkpoint}, user {user}"
          f"{', stream' if args.stream else ''}: {metrics_summary(run.tasks, metrics)}")
    print(f"done: outputs in {out}")


def _check_arguments(args: argparse.Namespace) -> None:
    """Before TensorFlow loads: the run, its data folder (recorded or ``--data-dir``), the user
    whose trials are scored among its file names, and ``--out``."""
    from jigsaws_tools.recording_format import load_format
    from jigsaws_tools.release import require_user

    config = read_run_config(args.run_dir)[0]
    fmt = load_format(args.format) if args.format else config.data.recording_format
    require_user(data_folder(config, args.run_dir, args.data_dir),
                 args.test_user or config.test_user, config.data.task, fmt)
    if args.out is not None:
        check_evaluation_folder(args.out, args.overwrite)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    advice = stream_layout_advice("the layout the run trained on", "evaluate")
    return run_command(PROG, args.verbose, lambda: _evaluate(args),
                       layout_advice=advice if args.stream else None, argv=argv)


if __name__ == "__main__":
    sys.exit(main())
