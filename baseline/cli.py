"""``baseline-train``: train DiPietro's model A (or its forward twin) on one LOUO fold."""
from __future__ import annotations

import argparse
import sys

from jigsaws_tools.cli.common import command_parser, run_command
from rnn_seg.config import OptimConfig
from rnn_seg.runs.provenance import set_command

from .config import RunConfig
from .options import add_run_arguments, run_config_from_args

PROG = "baseline-train"
#: The first line a training prints, after "model: ", of its ``--direction``.
MODEL_NAME = "A (gestures only), DiPietro et al.'s LSTM, {direction}"


def build_parser() -> argparse.ArgumentParser:
    parser = command_parser(PROG, __doc__)
    add_run_arguments(parser, OptimConfig())
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    set_command([PROG, *(sys.argv[1:] if argv is None else argv)])
    return run_command(PROG, args.verbose, lambda: _train(args), argv=argv)


def _train(args: argparse.Namespace) -> int:
    """Configure (no data read, no TensorFlow), take the run folder's lock, train; returns the
    exit code."""
    from .launch import run_training

    def configure() -> RunConfig:
        config = run_config_from_args(args, OptimConfig())
        print(f"model: {MODEL_NAME.format(direction=args.direction)}\n{config.describe()}",
              flush=True)
        return config

    def train(config: RunConfig) -> dict:
        from rnn_seg.threads import configure_threads

        from .builder import train_baseline

        configure_threads(args.threads, args.hidden, args.precision,
                          bidirectional=args.direction == "bidirectional")
        return train_baseline(config, args.out, log=lambda m: print(m, flush=True),
                              restart=args.restart)

    code, result = run_training(PROG, args.out, configure, train)
    if result is None:
        return code
    mean = result["mean"]["gesture"]
    print(f"done: gesture accuracy {mean['accuracy']:.1f}, edit {mean['edit']:.1f}, "
          f"F1@10 {mean['f1@10']:.1f} (mean over evaluation points); outputs in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
