"""Command-line options shared by every training CLI, and the run configuration they build.

Every default shown comes from the configuration dataclasses (``DataConfig``, ``EncoderConfig``,
``OptimConfig``, ``TrainConfig``, ``RunConfig``), so it is stated in one place.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from jigsaws_tools.annotations import ANNOTATION_VERSIONS
from jigsaws_tools.dataset import DataConfig, default_cache_dir, default_data_dir
from jigsaws_tools.features import FEATURE_SETS
from jigsaws_tools.synth import SynthConfig, ensure_release
from jigsaws_tools.task_options import add_task_options, task_from_options
from rnn_seg.checkpoints import KEEP_CHECKPOINTS
from rnn_seg.lstm import PRECISIONS, RESET_MODES, EncoderConfig
from rnn_seg.optim import OptimConfig
from rnn_seg.trainer import PLOT_POINTS, PREDICTION_MODES, TrainConfig, check_eval_points

from .config import RunConfig


def add_run_arguments(parser: argparse.ArgumentParser, optim: OptimConfig) -> None:
    """Options shared by every training CLI; ``optim`` supplies the defaults shown."""
    encoder, train = EncoderConfig(), TrainConfig()
    data = parser.add_argument_group("data")
    source = data.add_mutually_exclusive_group()
    source.add_argument("--data-dir", type=Path, help="JIGSAWS Suturing folder "
                        f"(default: $JIGSAWS_DIR or {default_data_dir()})")
    source.add_argument("--synthetic", action="store_true",
                        help="use the embedded synthetic release (written once to the cache)")
    data.add_argument("--synthetic-seed", type=int, default=SynthConfig.seed)
    data.add_argument("--test-user", default=RunConfig.test_user, help="user held out (LOUO fold)")
    data.add_argument("--annotations", choices=ANNOTATION_VERSIONS, default=DataConfig.annotations)
    data.add_argument("--features", choices=list(FEATURE_SETS), default=DataConfig.feature_set)
    add_task_options(data)
    model = parser.add_argument_group("model")
    model.add_argument("--hidden", type=int, default=encoder.hidden)
    model.add_argument("--layers", type=int, default=encoder.layers)
    model.add_argument("--direction", choices=("bidirectional", "forward"), default="bidirectional",
                       help="forward = the online twin")
    model.add_argument("--keep-prob", type=float, default=encoder.keep_prob)
    model.add_argument("--init-scale", type=float, default=encoder.init_scale)
    model.add_argument("--reset-mode", choices=RESET_MODES, default=encoder.reset_mode)
    model.add_argument("--precision", choices=PRECISIONS, default=encoder.precision,
                       help="of the LSTM's matrix products: bf16 needs a CPU with native "
                            "bfloat16 (docs/PERFORMANCE.md)")
    opt = parser.add_argument_group("optimisation")
    length = opt.add_mutually_exclusive_group()
    length.add_argument("--epochs", type=int, help=f"train for N epochs (default {optim.total})")
    length.add_argument("--sweeps", type=int, help="train for N sweeps instead")
    opt.add_argument("--decay-start", type=int, default=None,
                     help=f"units at the initial learning rate (default {optim.decay_start}, "
                          "or 2/3 of --epochs/--sweeps when those are given)")
    opt.add_argument("--decay-every", type=int, default=optim.decay_every)
    opt.add_argument("--decay-factor", type=float, default=optim.decay_factor)
    opt.add_argument("--lr", type=float, default=optim.learning_rate)
    opt.add_argument("--momentum", type=float, default=optim.momentum)
    opt.add_argument("--clip-norm", type=float, default=optim.clip_norm)
    opt.add_argument("--batch-size", type=int, default=train.batch_size)
    run = parser.add_argument_group("run")
    run.add_argument("--seed", type=int, default=train.seed)
    run.add_argument("--eval-at", default=None,
                     help="comma-separated evaluation points in the schedule's unit "
                          "(default: the paper's, e.g. 100,110,120 of 120 epochs; the final "
                          "unit when --epochs/--sweeps change the length)")
    run.add_argument("--prediction", choices=PREDICTION_MODES, default=train.prediction)
    run.add_argument("--plots", choices=PLOT_POINTS, default=train.plots,
                     help="evaluation points that draw a figure per test sequence")
    run.add_argument("--no-plots", dest="plots", action="store_const", const="none",
                     help="same as --plots none")
    run.add_argument("--monitor-every", type=int, default=train.monitor_every,
                     help="units (epochs) between test-set scores on the progress line; the "
                          "last unit is always scored; evaluation points are unaffected")
    run.add_argument("--monitor-train", action="store_true",
                     help="also score the training set on those progress lines (slow)")
    run.add_argument("--tensorboard", action="store_true",
                     help="also write the progress scalars to RUN_DIR/tensorboard")
    run.add_argument("--threads", type=int, default=0,
                     help="cores for this run (0 = all), split between TensorFlow's thread pools "
                          "as rnn_seg.threads measures best")
    run.add_argument("--out", type=Path, required=True, help="run directory")
    run.add_argument("--restart", action="store_true",
                     help="delete the run directory's previous config and results and train "
                          "afresh (needed when it holds a run with other settings)")
    run.add_argument("--keep-checkpoints", choices=KEEP_CHECKPOINTS, default=train.keep_checkpoints,
                     help="what a finished run keeps: its final weights, also the weights of "
                          "every evaluation point, or every checkpoint")


def run_config_from_args(args: argparse.Namespace, optim: OptimConfig,
                         eval_points: tuple[int, ...] = TrainConfig.eval_points) -> RunConfig:
    """Build the run's configuration from parsed options over the defaults in ``optim``;
    ``eval_points`` apply when the schedule keeps its default length, else the last unit. Every
    value is checked by the configuration dataclasses (``ValueError`` naming field, range and
    value) before the data is read."""
    task = task_from_options(args)
    if args.sweeps is not None:
        unit, total = "sweeps", args.sweeps
    else:
        unit, total = "epochs", optim.total if args.epochs is None else args.epochs
    default_length = unit == "epochs" and total == optim.total
    decay_start = args.decay_start if args.decay_start is not None else (
        optim.decay_start if default_length else (2 * total) // 3)
    if args.eval_at is not None:
        eval_points = _parse_points(args.eval_at)
    else:
        eval_points = eval_points if default_length else (total,)
    encoder = EncoderConfig(hidden=args.hidden, layers=args.layers,
                            bidirectional=args.direction == "bidirectional",
                            keep_prob=args.keep_prob, init_scale=args.init_scale,
                            reset_mode=args.reset_mode, precision=args.precision)
    optim = OptimConfig(learning_rate=args.lr, momentum=args.momentum, clip_norm=args.clip_norm,
                        unit=unit, total=total, decay_start=decay_start,
                        decay_every=args.decay_every, decay_factor=args.decay_factor)
    train = TrainConfig(batch_size=args.batch_size, seed=args.seed, eval_points=eval_points,
                        prediction=args.prediction, plots=args.plots,
                        monitor_every=args.monitor_every, monitor_train=args.monitor_train,
                        tensorboard=args.tensorboard, keep_checkpoints=args.keep_checkpoints)
    check_eval_points(eval_points, optim)
    if args.synthetic:
        data_dir = ensure_release(default_cache_dir(), SynthConfig(seed=args.synthetic_seed), task)
    else:
        data_dir = args.data_dir or default_data_dir(task.name)
    data = DataConfig(str(data_dir), feature_set=args.features, annotations=args.annotations,
                      task=task)
    return RunConfig(data=data, test_user=args.test_user, encoder=encoder, optim=optim,
                     train=train)


def _parse_points(text: str) -> tuple[int, ...]:
    """``"100,110,120"`` -> ``(100, 110, 120)``; anything else is a ``ValueError`` naming it."""
    try:
        return tuple(int(p) for p in text.split(","))
    except ValueError:
        raise ValueError(f"--eval-at must be comma-separated integers, e.g. 100,110,120 "
                         f"(got {text!r})") from None
