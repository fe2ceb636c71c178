"""``multitask-train``: train one of A, APr, APc, APoc, Pr, Pc, Poc on one LOUO fold.

``--help`` shows the defaults of the chosen ``--variant`` (each has the paper's optimiser) and
``--encoder`` (a temporal-convolution encoder has its reference's, for every variant).
"""
from __future__ import annotations

import argparse
import sys

from dataclasses import replace

from baseline.config import RunConfig
from baseline.options import add_run_arguments, run_config_from_args
from rnn_seg.config import EncoderConfig
from rnn_seg.encoders.config import ENCODERS, encoder_config
from jigsaws_tools.cli.arg_types import non_negative_float, positive_float
from jigsaws_tools.cli.common import command_parser, import_tensorflow, run_command
from rnn_seg.runs.provenance import set_command

from .models.config import ORDINAL_LOSSES, RELATIVE_RATES, WEIGHTINGS, GradNormConfig, HeadConfig
from .models.variants import VARIANTS, Variant, batch_size, get_variant

PROG = "multitask-train"
DEFAULT_VARIANT = "APc"


def add_variant_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--variant", choices=list(VARIANTS), default=DEFAULT_VARIANT,
                        help="A = gestures only; APr / APc / APoc = gestures + progress by "
                             "regression / classification / ordered classification; Pr / Pc / "
                             "Poc = progress only")


#: The LSTM's options (``EncoderConfig``): refused with a temporal-convolution encoder.
LSTM_OPTIONS = {"hidden": "--hidden", "layers": "--layers", "keep_prob": "--keep-prob",
                "init_scale": "--init-scale", "reset_mode": "--reset-mode",
                "precision": "--precision", "loops": "--loops"}


def add_encoder_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--encoder", choices=ENCODERS, default=ENCODERS[0],
                        help="the shared encoder: DiPietro's peephole BiLSTM (the paper's), Lea "
                             "et al.'s ED-TCN or Farha & Gall's MS-TCN, each with its "
                             "reference's settings and optimiser (docs/REPRODUCTION.md); "
                             "--direction forward makes a TCN's convolutions causal")


def build_parser(variant_name: str = DEFAULT_VARIANT, encoder: str = ENCODERS[0]
                 ) -> argparse.ArgumentParser:
    """The parser, its schedule defaults those of variant ``variant_name`` on ``encoder``."""
    variant = get_variant(variant_name)
    parser = command_parser(PROG, __doc__)
    add_variant_argument(parser)
    add_encoder_argument(parser)
    parser.add_argument("--weighting", choices=WEIGHTINGS, default=WEIGHTINGS[0],
                        help="task loss weights: fixed w1 = w2 = 1, or GradNorm (two-task "
                             "variants only)")
    parser.add_argument("--alpha", type=non_negative_float,
                        help=f"GradNorm's asymmetry alpha (default: {GradNormConfig.alpha})")
    parser.add_argument("--weight-lr", type=positive_float, metavar="LR",
                        help="learning rate of the GradNorm task weights (default: "
                             f"{GradNormConfig.learning_rate})")
    parser.add_argument("--relative-rate", choices=RELATIVE_RATES,
                        help="GradNorm's r_i divides the loss ratios by their mean (chen) or by "
                             "the mean loss (paper's literal text) (default: "
                             f"{GradNormConfig.relative_rate})")
    parser.add_argument("--ordinal-loss", choices=ORDINAL_LOSSES,
                        help="the ordered progress head's cross-entropy over its outputs (one "
                             "per stage): summed (the paper's MBCE) or averaged (default: "
                             f"{HeadConfig.ordinal_loss})")
    add_run_arguments(parser, variant.optim(encoder), variant.eval_points(encoder),
                      batch_size(encoder))
    if encoder != "lstm":                       # given or not: None unless given (refused)
        parser.set_defaults(**{name: None for name in LSTM_OPTIONS})
    return parser


def main(argv: list[str] | None = None) -> int:
    pre = argparse.ArgumentParser(add_help=False)
    add_variant_argument(pre)
    add_encoder_argument(pre)
    known, _ = pre.parse_known_args(argv)
    variant = get_variant(known.variant)
    parser = build_parser(variant.name, known.encoder)
    args = parser.parse_args(argv)
    unused = _unused_options(args, variant)
    if unused:
        parser.refuse(unused)
    set_command([PROG, *(sys.argv[1:] if argv is None else argv)])
    return run_command(PROG, args.verbose, lambda: _train(args, variant))


def _unused_options(args: argparse.Namespace, variant: Variant) -> str | None:
    """Why an option given does not apply to the run asked for (it would be silently ignored):
    GradNorm's without ``--weighting gradnorm``, ``--ordinal-loss`` without an ordered head."""
    gradnorm = [o for o, v in (("--alpha", args.alpha), ("--weight-lr", args.weight_lr),
                               ("--relative-rate", args.relative_rate)) if v is not None]
    if gradnorm and args.weighting != "gradnorm":
        return f"{gradnorm[0]} is a GradNorm setting; add --weighting gradnorm, or leave it out"
    if args.ordinal_loss is not None and variant.progress != "oc":
        return (f"--ordinal-loss applies to an ordered progress head (APoc, Poc), not to "
                f"variant {variant.name}")
    if args.encoder != "lstm":
        given = [option for name, option in LSTM_OPTIONS.items() if getattr(args, name) is not None]
        if given:
            return (f"{given[0]} is an LSTM setting; the {args.encoder} encoder has its "
                    "reference's (docs/REPRODUCTION.md): leave it out, or use --encoder lstm")
    return None


def _with_encoder(args: argparse.Namespace, config: RunConfig) -> RunConfig:
    """``config`` with ``--encoder``'s configuration: a TCN's (causal for ``--direction
    forward``) in place of the LSTM options' defaults."""
    if args.encoder == "lstm":
        return config
    return replace(config, encoder=encoder_config(args.encoder,
                                                  causal=args.direction == "forward"))


def _train(args: argparse.Namespace, variant: Variant) -> int:
    """Configure (no data read), take the run folder's lock, train; returns the exit code."""
    import_tensorflow()
    from baseline.launch import run_training
    from rnn_seg.threads import configure_threads

    from .models.fold_run import check_weighting, train_variant

    def configure() -> tuple[RunConfig, GradNormConfig, HeadConfig]:
        for name in LSTM_OPTIONS:                 # a TCN's: refused when given, so defaults
            if getattr(args, name) is None:
                setattr(args, name, getattr(EncoderConfig, name))
        config = _with_encoder(args, run_config_from_args(args, variant.optim(args.encoder),
                                                          variant.eval_points(args.encoder)))
        gradnorm = GradNormConfig(**_given(alpha=args.alpha, learning_rate=args.weight_lr,
                                           relative_rate=args.relative_rate))
        heads = HeadConfig(**_given(ordinal_loss=args.ordinal_loss))
        check_weighting(variant, args.weighting)
        configure_threads(args.threads, config.encoder.hidden, config.encoder.precision,
                          bidirectional=args.direction == "bidirectional")
        print(f"variant: {variant.name} ({args.weighting}, encoder {args.encoder})\n"
              f"{config.describe()}", flush=True)
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


def _given(**values) -> dict:
    """The values an option set (the rest keep their configuration's default)."""
    return {name: value for name, value in values.items() if value is not None}


if __name__ == "__main__":
    sys.exit(main())
