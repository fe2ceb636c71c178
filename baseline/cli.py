"""``baseline-train``: train DiPietro's model A (or its forward twin) on one LOUO fold."""
from __future__ import annotations

import argparse
import logging
import os
import sys

from rnn_seg.optim import OptimConfig
from rnn_seg.provenance import set_command
from rnn_seg.threads import configure_threads

from .builder import train_baseline
from .config import RunConfig
from .launch import run_training
from .options import add_run_arguments, run_config_from_args


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    logging.basicConfig(format="%(levelname)s: %(message)s", level=logging.WARNING)
    parser = argparse.ArgumentParser(prog="baseline-train", description=__doc__)
    add_run_arguments(parser, OptimConfig())
    args = parser.parse_args(argv)
    set_command(["baseline-train", *(sys.argv[1:] if argv is None else argv)])

    def configure() -> RunConfig:
        config = run_config_from_args(args, OptimConfig())
        configure_threads(args.threads, args.hidden)
        print(config.describe(), flush=True)
        return config

    def train(config: RunConfig) -> dict:
        return train_baseline(config, args.out, log=lambda m: print(m, flush=True),
                              restart=args.restart)

    code, result = run_training("baseline-train", args.out, configure, train)
    if result is None:
        return code
    mean = result["mean"]["gesture"]
    print(f"done: gesture accuracy {mean['accuracy']:.1f}, edit {mean['edit']:.1f}, "
          f"F1@10 {mean['f1@10']:.1f} (mean over evaluation points); outputs in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
