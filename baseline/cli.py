"""``baseline-train``: train DiPietro's model A (or its forward twin) on one LOUO fold."""
from __future__ import annotations

import argparse
import sys

from jigsaws_tools.cli_common import command_parser, import_tensorflow, run_command
from rnn_seg.config import OptimConfig

from .options import add_run_arguments, run_config_from_args

PROG = "baseline-train"


def build_parser() -> argparse.ArgumentParser:
    parser = command_parser(PROG, __doc__)
    add_run_arguments(parser, OptimConfig())
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return run_command(PROG, args.verbose, lambda: _train(args))


def _train(args: argparse.Namespace) -> None:
    import_tensorflow()
    from rnn_seg.threads import configure_threads

    from .builder import train_baseline

    configure_threads(args.threads, args.hidden)
    config = run_config_from_args(args, OptimConfig())
    print(config.describe(), flush=True)
    result = train_baseline(config, args.out, log=lambda m: print(m, flush=True))
    mean = result["mean"]["gesture"]
    print(f"done: gesture accuracy {mean['accuracy']:.1f}, edit {mean['edit']:.1f}, "
          f"F1@10 {mean['f1@10']:.1f} (mean over evaluation points); outputs in {args.out}")


if __name__ == "__main__":
    sys.exit(main())
