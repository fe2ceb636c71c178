"""``multitask-train``: train one of A, APr, APc, APoc, Pr, Pc, Poc on one LOUO fold.

``--help`` shows the defaults of the chosen ``--variant`` (each has the paper's optimiser) and
``--encoder`` (a temporal-convolution encoder has its reference's, for every variant; a user's
encoder, ``--encoder package.module:name``, the LSTM's: docs/YOUR_METHOD.md).
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Callable

from baseline.config import RunConfig
from baseline.options import add_run_arguments, run_config_from_args
from jigsaws_tools.cli.arg_types import non_negative_float, positive_float
from jigsaws_tools.cli.common import command_parser, run_command
from rnn_seg.config import EncoderConfig
from rnn_seg.encoders.config import ENCODERS, encoder_config
from rnn_seg.encoders.import_path import is_import_path, split_path
from rnn_seg.runs.provenance import set_command

from .models.config import ORDINAL_LOSSES, RELATIVE_RATES, WEIGHTINGS, GradNormConfig, HeadConfig
from .models.variants import VARIANTS, Variant, batch_size, check_weighting, get_variant

PROG = "multitask-train"
DEFAULT_VARIANT = "APc"


def add_variant_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--variant", choices=list(VARIANTS), default=DEFAULT_VARIANT,
                        help="A = gestures only; APr / APc / APoc = gestures + progress by "
                             "regression / classification / ordered classification; Pr / Pc / "
                             "Poc = progress only")


#: The LSTM's options (``EncoderConfig``): refused with another encoder.
LSTM_OPTIONS = {"hidden": "--hidden", "layers": "--layers", "keep_prob": "--keep-prob",
                "init_scale": "--init-scale", "reset_mode": "--reset-mode",
                "precision": "--precision", "loops": "--loops"}


def encoder_name(text: str) -> str:
    """``--encoder``'s value: a built-in encoder's name or a user's encoder's import path."""
    if text in ENCODERS:
        return text
    if not is_import_path(text):
        raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from "
                                         f"{', '.join(ENCODERS)}, or package.module:name)")
    try:
        split_path(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text


def add_encoder_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--encoder", type=encoder_name, default=ENCODERS[0],
                        metavar="{" + ",".join(ENCODERS) + "} or package.module:name",
                        help="the shared encoder: DiPietro's peephole BiLSTM (the paper's), Lea "
                             "et al.'s ED-TCN or Farha & Gall's MS-TCN, each with its "
                             "reference's settings and optimiser (docs/REPRODUCTION.md); "
                             "--direction forward makes a TCN's convolutions causal; or your "
                             "own, a function or class building a Keras layer, by its import "
                             "path, trained on the LSTM's schedule (docs/YOUR_METHOD.md)")


def build_parser(variant_name: str = DEFAULT_VARIANT, encoder: str = ENCODERS[0]
                 ) -> argparse.ArgumentParser:
    """The parser, its schedule defaults those of variant ``variant_name`` on ``encoder``."""
    variant = get_variant(variant_name)
    parser = command_parser(PROG, __doc__)
    add_variant_argument(parser)
    add_encoder_argument(parser)
    parser.add_argument("--weighting", choices=WEIGHTINGS, default=None,
                        help="task loss weights: fixed w1 = w2 = 1, or GradNorm (two-task "
                             f"variants only; the paper's) (default: {WEIGHTINGS[0]})")
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
    parser.add_argument("--mlflow", metavar="URI",
                        help="also log the run to MLflow once it finishes: settings, the "
                             "metrics of every history.csv row, final scores "
                             "(sqlite:///mlflow.db, http://host:5000, ...; needs "
                             "pip install -e '.[mlflow]'; default: none)")
    return parser


def main(argv: list[str] | None = None) -> int:
    pre = argparse.ArgumentParser(add_help=False)      # whose defaults --help shows
    pre.add_argument("--variant", default=DEFAULT_VARIANT)
    pre.add_argument("--encoder", default=ENCODERS[0])
    known, _ = pre.parse_known_args(argv)
    parser = build_parser(known.variant if known.variant in VARIANTS else DEFAULT_VARIANT,
                          known.encoder if is_import_path(known.encoder)
                          or known.encoder in ENCODERS else ENCODERS[0])
    args = parser.parse_args(argv)                     # refuses an unknown variant
    variant = get_variant(args.variant)
    unused = unused_options(args, variant)
    if unused:
        parser.refuse(unused)
    set_command([PROG, *(sys.argv[1:] if argv is None else argv)])
    return run_command(PROG, args.verbose, lambda: _train(args, variant), argv=argv)


def unused_options(args: argparse.Namespace, variant: Variant) -> str | None:
    """Why an option given does not apply to the run asked for (it would be silently ignored):
    GradNorm's without ``--weighting gradnorm``, ``--ordinal-loss`` without an ordered head."""
    gradnorm = [o for o, v in (("--alpha", args.alpha), ("--weight-lr", args.weight_lr),
                               ("--relative-rate", args.relative_rate)) if v is not None]
    if gradnorm and weighting(args) != "gradnorm":
        return f"{gradnorm[0]} is a GradNorm setting; add --weighting gradnorm, or leave it out"
    if args.ordinal_loss is not None and variant.progress != "oc":
        return (f"--ordinal-loss applies to an ordered progress head (APoc, Poc), not to "
                f"variant {variant.name}")
    if args.encoder != "lstm":
        given = [option for name, option in LSTM_OPTIONS.items() if getattr(args, name) is not None]
        if given:
            own = ("its own" if is_import_path(args.encoder)
                   else "its reference's (docs/REPRODUCTION.md)")
            return (f"{given[0]} is an LSTM setting; the {args.encoder} encoder has {own}: "
                    "leave it out, or use --encoder lstm")
    return None


def weighting(args: argparse.Namespace) -> str:
    """The task weighting the options ask for (``--weighting``, default fixed)."""
    return args.weighting or WEIGHTINGS[0]


def configure_run(args: argparse.Namespace, variant: Variant, log: Callable[[str], None]
                  ) -> tuple[RunConfig, GradNormConfig, HeadConfig]:
    """The run's configurations from parsed options (no data read, no TensorFlow), the model's
    full name (its weighting included) and the configuration said in ``log``; a bad value is a
    ``ValueError``."""
    gradnorm = GradNormConfig(**_given(alpha=args.alpha, learning_rate=args.weight_lr,
                                       relative_rate=args.relative_rate))
    heads = HeadConfig(**_given(ordinal_loss=args.ordinal_loss))
    check_weighting(variant, weighting(args))
    for name in LSTM_OPTIONS:                 # a TCN's: refused when given, so defaults
        if getattr(args, name) is None:
            setattr(args, name, getattr(EncoderConfig, name))
    config = _with_encoder(args, run_config_from_args(args, variant.optim(args.encoder),
                                                      variant.eval_points(args.encoder)))
    encoder = "" if args.encoder == "lstm" else f", encoder {args.encoder}"
    log(f"model: {variant.full_name(weighting(args), gradnorm, args.weighting is not None)}"
        f"{encoder}\n{config.describe()}")
    return config, gradnorm, heads


def _with_encoder(args: argparse.Namespace, config: RunConfig) -> RunConfig:
    """``config`` with ``--encoder``'s configuration: a TCN's, or a user's encoder's with its
    source's hash (causal for ``--direction forward``), in place of the LSTM options'
    defaults."""
    if args.encoder == "lstm":
        return config
    return replace(config, encoder=encoder_config(args.encoder,
                                                  causal=args.direction == "forward"))


def train_configured(args: argparse.Namespace, variant: Variant,
                     configs: tuple[RunConfig, GradNormConfig, HeadConfig],
                     log: Callable[[str], None]) -> dict:
    """Train the run ``configure_run`` configured (TensorFlow's threads set first); its
    metrics."""
    from rnn_seg.threads import configure_threads

    from .models.fold_run import train_variant

    config, gradnorm, heads = configs
    configure_threads(args.threads, config.encoder.hidden, config.encoder.precision,
                      bidirectional=args.direction == "bidirectional")
    return train_variant(variant, weighting(args), config, args.out, gradnorm, log=log,
                         heads=heads, restart=args.restart)


def log_to_mlflow(tracker, run_dir: Path, log: Callable[[str], None]) -> None:
    """Log the finished run in ``run_dir`` with ``tracker`` (``rnn_seg.runs.tracking``) and say
    where; a failure is a warning line (the run itself is complete)."""
    try:
        tracker.log_run(run_dir)
    except Exception as error:                        # MLflow's errors have no common base
        log(f"warning: the run was not logged to MLflow at {tracker.uri}: "
            f"{type(error).__name__}: {error}")
        return
    log(f"mlflow: {run_dir} logged to {tracker.uri}")


def _train(args: argparse.Namespace, variant: Variant) -> int:
    """Configure (no data read, no TensorFlow), take the run folder's lock, train; returns the
    exit code. The model's full name, its weighting included, is the first line printed."""
    from baseline.launch import run_training
    from rnn_seg.runs.tracking import Tracker

    tracker = Tracker(args.mlflow) if args.mlflow else None      # checked before any work

    def say(message: str) -> None:
        print(message, flush=True)

    code, result = run_training(PROG, args.out, lambda: configure_run(args, variant, say),
                                lambda configs: train_configured(args, variant, configs, say))
    if result is None:
        return code
    if tracker is not None:
        log_to_mlflow(tracker, args.out, say)
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
