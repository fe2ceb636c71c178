"""``multitask-train``: train one of A, APr, APc, APoc, Pr, Pc, Poc on one LOUO fold.

``--help`` shows the defaults of the chosen ``--variant`` (each has the paper's optimiser).
"""
from __future__ import annotations

import argparse
import sys

from baseline.config import RunConfig
from baseline.options import add_run_arguments, run_config_from_args
from jigsaws_tools.cli.arg_types import non_negative_float, positive_float
from jigsaws_tools.cli.common import command_parser, import_tensorflow, run_command
from rnn_seg.runs.provenance import set_command

from .models.config import ORDINAL_LOSSES, RELATIVE_RATES, WEIGHTINGS, GradNormConfig, HeadConfig
from .models.variants import VARIANTS, Variant, get_variant

PROG = "multitask-train"
DEFAULT_VARIANT = "APc"


def add_variant_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--variant", choices=list(VARIANTS), default=DEFAULT_VARIANT,
                        help="A = gestures only; APr / APc / APoc = gestures + progress by "
                             "regression / classification / ordered classification; Pr / Pc / "
                             "Poc = progress only")


def build_parser(variant_name: str = DEFAULT_VARIANT) -> argparse.ArgumentParser:
    """The parser, its schedule defaults those of variant ``variant_name``."""
    variant = get_variant(variant_name)
    parser = command_parser(PROG, __doc__)
    add_variant_argument(parser)
    parser.add_argument("--weighting", choices=WEIGHTINGS, default=WEIGHTINGS[0],
                        help="task loss weights: fixed w1 = w2 = 1, or GradNorm (two-task "
                             "variants only)")
    parser.add_argument("--alpha", type=non_negative_float, default=GradNormConfig.alpha,
                        help="GradNorm's asymmetry alpha")
    parser.add_argument("--weight-lr", type=positive_float, default=GradNormConfig.learning_rate,
                        metavar="LR", help="learning rate of the GradNorm task weights")
    parser.add_argument("--relative-rate", choices=RELATIVE_RATES,
                        default=GradNormConfig.relative_rate,
                        help="GradNorm's r_i divides the loss ratios by their mean (chen) or by "
                             "the mean loss (paper's literal text)")
    parser.add_argument("--ordinal-loss", choices=ORDINAL_LOSSES, default=HeadConfig.ordinal_loss,
                        help="the ordered progress head's cross-entropy over its outputs (one "
                             "per stage): summed (the paper's MBCE) or averaged")
    add_run_arguments(parser, variant.optim(), variant.eval_points())
    return parser


def main(argv: list[str] | None = None) -> int:
    pre = argparse.ArgumentParser(add_help=False)
    add_variant_argument(pre)
    known, _ = pre.parse_known_args(argv)
    variant = get_variant(known.variant)
    args = build_parser(variant.name).parse_args(argv)
    set_command([PROG, *(sys.argv[1:] if argv is None else argv)])
    return run_command(PROG, args.verbose, lambda: _train(args, variant))


def _train(args: argparse.Namespace, variant: Variant) -> int:
    """Configure (no data read), take the run folder's lock, train; returns the exit code."""
    import_tensorflow()
    from baseline.launch import run_training
    from rnn_seg.threads import configure_threads

    from .models.fold_run import check_weighting, train_variant

    def configure() -> tuple[RunConfig, GradNormConfig, HeadConfig]:
        config = run_config_from_args(args, variant.optim(), variant.eval_points())
        gradnorm = GradNormConfig(alpha=args.alpha, learning_rate=args.weight_lr,
                                  relative_rate=args.relative_rate)
        heads = HeadConfig(ordinal_loss=args.ordinal_loss)
        check_weighting(variant, args.weighting)
        configure_threads(args.threads, args.hidden, args.precision,
                          bidirectional=args.direction == "bidirectional")
        print(f"variant: {variant.name} ({args.weighting})\n{config.describe()}", flush=True)
        return config, gradnorm, heads

    def train(configs: tuple[RunConfig, GradNormConfig, HeadConfig]) -> dict:
        config, gradnorm, heads = configs
        return train_variant(variant, args.weighting, config, args.out, gradnorm,
                             log=lambda m: print(m, flush=True), heads=heads,
                             restart=args.restart)

    code, result = run_training(PROG, args.out, configure, train)
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
