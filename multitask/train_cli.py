"""``multitask-train``: train one of A, APr, APc, APoc, Pr, Pc, Poc on one LOUO fold."""
from __future__ import annotations

import argparse
import logging
import os
import sys

from baseline.config import RunConfig
from baseline.launch import run_training
from baseline.options import add_run_arguments, run_config_from_args
from rnn_seg.provenance import set_command
from rnn_seg.threads import configure_threads

from .fold_run import WEIGHTINGS, check_weighting, train_variant
from .gradnorm import RELATIVE_RATES, GradNormConfig
from .heads import ORDINAL_LOSSES, HeadConfig
from .variants import VARIANTS, get_variant


def build_parser(variant_name: str) -> argparse.ArgumentParser:
    variant = get_variant(variant_name)
    parser = argparse.ArgumentParser(prog="multitask-train", description=__doc__)
    parser.add_argument("--variant", choices=list(VARIANTS), default="APc")
    parser.add_argument("--weighting", choices=WEIGHTINGS, default="fixed")
    parser.add_argument("--alpha", type=float, default=GradNormConfig.alpha)
    parser.add_argument("--weight-lr", type=float, default=GradNormConfig.learning_rate,
                        help="learning rate of the GradNorm task weights")
    parser.add_argument("--relative-rate", choices=RELATIVE_RATES,
                        default=GradNormConfig.relative_rate,
                        help="GradNorm's r_i divides the loss ratios by their mean (chen) or by "
                             "the mean loss (paper's literal text)")
    parser.add_argument("--ordinal-loss", choices=ORDINAL_LOSSES, default=HeadConfig.ordinal_loss,
                        help="the ordered progress head's cross-entropy over its outputs: "
                             "summed (the paper's MBCE) or averaged")
    add_run_arguments(parser, variant.optim())
    return parser


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    logging.basicConfig(format="%(levelname)s: %(message)s", level=logging.WARNING)
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--variant", choices=list(VARIANTS), default="APc")
    known, _ = pre.parse_known_args(argv)
    variant = get_variant(known.variant)
    args = build_parser(variant.name).parse_args(argv)
    set_command(["multitask-train", *(sys.argv[1:] if argv is None else argv)])

    def configure() -> tuple[RunConfig, GradNormConfig, HeadConfig]:
        config = run_config_from_args(args, variant.optim(), variant.eval_points())
        gradnorm = GradNormConfig(alpha=args.alpha, learning_rate=args.weight_lr,
                                  relative_rate=args.relative_rate)
        heads = HeadConfig(ordinal_loss=args.ordinal_loss)
        check_weighting(variant, args.weighting)
        configure_threads(args.threads, args.hidden)
        print(f"variant: {variant.name} ({args.weighting})\n{config.describe()}", flush=True)
        return config, gradnorm, heads

    def train(configs: tuple[RunConfig, GradNormConfig, HeadConfig]) -> dict:
        config, gradnorm, heads = configs
        return train_variant(variant, args.weighting, config, args.out, gradnorm,
                             log=lambda m: print(m, flush=True), heads=heads,
                             restart=args.restart)

    code, result = run_training("multitask-train", args.out, configure, train)
    if result is None:
        return code
    summary = "; ".join(f"{task}: accuracy {m['accuracy']:.1f}, edit {m['edit']:.1f}, "
                        f"F1@10 {m['f1@10']:.1f}" + (f", MAE {m['mae_normalised_rounded']:.1f}"
                                                     if "mae_normalised_rounded" in m else "")
                        for task, m in result["mean"].items())
    print(f"done: {summary} (mean over evaluation points); outputs in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
