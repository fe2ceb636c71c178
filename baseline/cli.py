"""``baseline-train``: train DiPietro's model A (or its forward twin) on one LOUO fold."""
from __future__ import annotations

import argparse
import logging
import os
import sys

from jigsaws_tools.errors import JigsawsError
from rnn_seg.optim import OptimConfig
from rnn_seg.threads import configure_threads

from .builder import train_baseline
from .options import add_run_arguments, run_config_from_args


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    logging.basicConfig(format="%(levelname)s: %(message)s", level=logging.WARNING)
    parser = argparse.ArgumentParser(prog="baseline-train", description=__doc__)
    add_run_arguments(parser, OptimConfig())
    args = parser.parse_args(argv)
    try:
        configure_threads(args.threads, args.hidden)
        config = run_config_from_args(args, OptimConfig())
        print(config.describe(), flush=True)
        result = train_baseline(config, args.out, log=lambda m: print(m, flush=True))
    except (JigsawsError, ValueError) as error:
        print(f"baseline-train: error: {error}", file=sys.stderr)
        return 2
    mean = result["mean"]["gesture"]
    print(f"done: gesture accuracy {mean['accuracy']:.1f}, edit {mean['edit']:.1f}, "
          f"F1@10 {mean['f1@10']:.1f} (mean over evaluation points); outputs in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
