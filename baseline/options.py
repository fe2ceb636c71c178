"""Command-line options shared by every training CLI, and the run configuration they build.

Every default shown comes from the configuration dataclasses (``DataConfig``, ``EncoderConfig``,
``OptimConfig``, ``TrainConfig``, ``RunConfig``), so it is stated in one place; none of them
imports TensorFlow, so ``--help`` does not either.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from jigsaws_tools.cli.arg_types import (momentum, non_negative_float, non_negative_int,
                                         positive_float, positive_int, positive_int_list,
                                         probability, thread_count)
from jigsaws_tools.dataset import DataConfig, check_format_fits
from jigsaws_tools.preprocessing import PreprocessConfig
from jigsaws_tools.release import require_layout, require_user
from jigsaws_tools.features import FEATURE_SETS
from jigsaws_tools.cli.format_options import add_format_option, format_from_options
from jigsaws_tools.cli.options import add_data_arguments, data_dir_from_args
from jigsaws_tools.cli.task_options import task_from_options
from rnn_seg.config import (KEEP_CHECKPOINTS, LOOPS, PLOT_POINTS, PRECISIONS, PREDICTION_MODES,
                            RESET_MODES, EncoderConfig, OptimConfig, TrainConfig,
                            check_eval_points, require_native_precision)

from .config import DIRECTIONS, RunConfig


def add_run_arguments(parser: argparse.ArgumentParser, optim: OptimConfig,
                      eval_points: tuple[int, ...] = TrainConfig.eval_points,
                      batch_size: int = TrainConfig.batch_size) -> None:
    """Options shared by every training CLI.

    Args:
        parser: the command's parser; the options go into groups data, model, optimisation, run.
        optim: the schedule whose values the options show as defaults (a variant's).
        eval_points: the default evaluation points shown by ``--eval-at``, in epochs.
        batch_size: the default of ``--batch-size`` (an encoder's).
    """
    _add_data_options(parser)
    _add_model_options(parser.add_argument_group("model"))
    _add_optimisation_options(parser.add_argument_group("optimisation"), optim, batch_size)
    _add_run_options(parser.add_argument_group("run"), eval_points)


def _add_data_options(parser: argparse.ArgumentParser) -> None:
    """The group "data": folder, task, labels, held-out user, features, recording format."""
    data = add_data_arguments(parser)
    add_test_user_argument(data)
    data.add_argument("--hold-out", type=_users, default=(), metavar="U[,U...]",
                      help="users in neither the training nor the test set: an outer fold's "
                           "test user, when --test-user is a validation user among its "
                           "training users (results/tcn/PLAN_factors.md)")
    data.add_argument("--features", choices=list(FEATURE_SETS), default=DataConfig.feature_set,
                      help="kinematic inputs: the paper's 14 PSM position, velocity and gripper "
                           "columns, all 38 PSM columns, or all 76")
    add_format_option(data, "the data folder's recordings")


def _add_model_options(model: argparse._ArgumentGroup) -> None:
    """The encoder's options (``EncoderConfig``)."""
    encoder = EncoderConfig()
    model.add_argument("--hidden", type=positive_int, default=encoder.hidden, metavar="H",
                       help="LSTM units per direction")
    model.add_argument("--layers", type=positive_int, default=encoder.layers, metavar="N",
                       help="stacked LSTM layers")
    model.add_argument("--direction", choices=DIRECTIONS, default=DIRECTIONS[0],
                       help="bidirectional (offline) or forward only (online)")
    model.add_argument("--keep-prob", type=probability, default=encoder.keep_prob, metavar="P",
                       help="dropout keep probability on each layer's inputs and outputs")
    model.add_argument("--init-scale", type=positive_float, default=encoder.init_scale,
                       metavar="S", help="initial weights uniform in [-S, S]")
    model.add_argument("--reset-mode", choices=RESET_MODES, default=encoder.reset_mode,
                       help="where the reverse direction restarts between wrapped sequences: as "
                            "in DiPietro's code, or before each sequence's last frame")
    model.add_argument("--precision", choices=PRECISIONS, default=encoder.precision,
                       help="of the LSTM's matrix products: bf16 needs a CPU with native "
                            "bfloat16 (docs/PERFORMANCE.md)")
    model.add_argument("--loops", choices=LOOPS, default=encoder.loops,
                       help="how the LSTM's loops over time run: TensorFlow ops step by step "
                            "(graph), compiled by XLA (xla), fused C++ ops built on first use "
                            "(fused), or auto: fused where they build, else graph (same results "
                            "to float32 rounding; docs/PERFORMANCE.md)")


def _add_optimisation_options(opt: argparse._ArgumentGroup, optim: OptimConfig,
                              batch_size: int) -> None:
    """The schedule's options (``OptimConfig``, defaults from ``optim``) and the batch size."""
    length = opt.add_mutually_exclusive_group()
    length.add_argument("--epochs", type=positive_int, metavar="N",
                        help=f"train for N epochs (default: {optim.total}, the paper's)")
    length.add_argument("--sweeps", type=positive_int, metavar="N",
                        help="train for N sweeps (optimisation steps) instead of epochs "
                             "(default: count epochs)")
    opt.add_argument("--decay-start", type=non_negative_int, default=None, metavar="N",
                     help=f"epochs (sweeps) at the initial learning rate (default: "
                          f"{optim.decay_start}, or 2/3 of --epochs/--sweeps when given)")
    opt.add_argument("--decay-every", type=positive_int, default=optim.decay_every, metavar="N",
                     help="epochs (sweeps) between learning-rate decays")
    opt.add_argument("--decay-factor", type=positive_float, default=optim.decay_factor,
                     metavar="F", help="learning-rate multiplier at each decay")
    opt.add_argument("--lr", type=positive_float, default=optim.learning_rate, metavar="LR",
                     help="initial learning rate")
    opt.add_argument("--momentum", type=momentum, default=optim.momentum, metavar="M",
                     help="SGD momentum in [0, 1); 0 = plain gradient descent")
    opt.add_argument("--clip-norm", type=non_negative_float, default=optim.clip_norm,
                     metavar="C", help="clip all gradients together to this global norm (0: no "
                                       f"clipping; optimiser: {optim.optimizer})")
    opt.add_argument("--batch-size", type=positive_int, default=batch_size,
                     metavar="B", help="sequences per sweep")


def _add_run_options(run: argparse._ArgumentGroup, eval_points: tuple[int, ...]) -> None:
    """What a run does besides training (``TrainConfig``): seed, evaluation, outputs, folder."""
    train = TrainConfig()
    run.add_argument("--seed", type=non_negative_int, default=train.seed, metavar="N",
                     help="seed of the initial weights, batch order and dropout")
    run.add_argument("--eval-at", type=positive_int_list, default=None, metavar="N,N,...",
                     help="evaluate the test user after these epochs (sweeps), saved under "
                          f"eval/ (default: {','.join(map(str, eval_points))} for the paper's "
                          "length, else the last epoch)")
    run.add_argument("--prediction", choices=PREDICTION_MODES, default=train.prediction,
                     help="test sequences wrapped into one sweep as in DiPietro's code, or each "
                          "predicted alone")
    run.add_argument("--plots", choices=PLOT_POINTS, default=train.plots,
                     help="evaluation points that draw a figure per test sequence")
    run.add_argument("--no-plots", dest="plots", action="store_const", const="none",
                     help="same as --plots none")
    run.add_argument("--monitor-every", type=non_negative_int, default=train.monitor_every,
                     metavar="N", help="epochs (sweeps) between test-set scores on the progress "
                                       "line (0: none but the last, which is always scored); "
                                       "evaluation points are unaffected")
    run.add_argument("--monitor-train", action="store_true",
                     help="also score the training set on those progress lines (slow)")
    run.add_argument("--tensorboard", action="store_true",
                     help="also write the progress scalars to RUN_DIR/tensorboard")
    add_threads_argument(run, "cores for this run (0 = all)")
    run.add_argument("--out", type=Path, required=True, metavar="DIR",
                     help="run folder; an unfinished run there resumes")
    run.add_argument("--restart", action="store_true",
                     help="delete the run folder's previous config and results and train afresh "
                          "(needed when it holds a run with other settings)")
    run.add_argument("--keep-checkpoints", choices=KEEP_CHECKPOINTS,
                     default=train.keep_checkpoints,
                     help="what a finished run keeps: its final weights, also the weights of "
                          "every evaluation point, or every checkpoint")


def _users(text: str) -> tuple[str, ...]:
    """``--hold-out``'s comma-separated user letters."""
    users = tuple(u.strip() for u in text.split(","))
    if not all(u.isalnum() for u in users):
        raise argparse.ArgumentTypeError(f"expected comma-separated user letters, got {text!r}")
    return users


def add_test_user_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--test-user U``: the user held out by the leave-one-user-out fold."""
    parser.add_argument("--test-user", default=RunConfig.test_user, metavar="U",
                        help="user held out for testing: the leave-one-user-out fold")


def add_threads_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup,
                         what: str, this_machine: bool = True) -> argparse.Action:
    """``--threads N``: cores per training run, shared by the training CLIs and the grid.
    ``this_machine``: at most the cores this process may use (else any count: the runs may train
    on other machines, whose workers check their own)."""
    count = thread_count if this_machine else non_negative_int
    return parser.add_argument("--threads", type=count, default=0, metavar="N",
                               help=f"{what}, split between TensorFlow's thread pools as "
                                    "rnn_seg.threads measures best")


def run_config_from_args(args: argparse.Namespace, optim: OptimConfig,
                         eval_points: tuple[int, ...] = TrainConfig.eval_points) -> RunConfig:
    """Build the run's configuration from parsed options. Every value is checked by the
    configuration dataclasses (``ValueError`` naming field, range and value) before the data is
    read, and the data folder's file names must hold trials of ``--test-user``. The data folder
    is recorded absolute, and as typed (``DataConfig.with_resolved_data_dir``).

    Args:
        args: options parsed by a parser built with ``add_run_arguments``.
        optim: the default schedule the options override (the one given to
            ``add_run_arguments``).
        eval_points: evaluation points, in epochs, used without ``--eval-at`` when the schedule
            keeps ``optim``'s length in epochs; otherwise the last unit is the only point.
    """
    task = task_from_options(args)
    optim, default_length = _schedule_from_args(args, optim)
    if args.eval_at is not None:
        eval_points = args.eval_at
    else:
        eval_points = eval_points if default_length else (optim.total,)
    encoder = EncoderConfig(hidden=args.hidden, layers=args.layers,
                            bidirectional=args.direction == "bidirectional",
                            keep_prob=args.keep_prob, init_scale=args.init_scale,
                            reset_mode=args.reset_mode, precision=args.precision,
                            loops=args.loops)
    train = TrainConfig(batch_size=args.batch_size, seed=args.seed, eval_points=eval_points,
                        prediction=args.prediction, plots=args.plots,
                        monitor_every=args.monitor_every, monitor_train=args.monitor_train,
                        tensorboard=args.tensorboard, keep_checkpoints=args.keep_checkpoints)
    check_eval_points(eval_points, optim)
    require_native_precision(encoder.precision)
    recording_format = format_from_options(args)
    check_format_fits(recording_format, args.features, PreprocessConfig(), args.format or "")
    data_dir = data_dir_from_args(args, task)
    require_layout(Path(data_dir), task, recording_format)  # before any output
    require_user(Path(data_dir), args.test_user, task, recording_format)   # file names only
    for user in args.hold_out:
        require_user(Path(data_dir), user, task, recording_format, "held-out user", "--hold-out")
    data = DataConfig(str(data_dir), feature_set=args.features, annotations=args.annotations,
                      task=task, recording_format=recording_format).with_resolved_data_dir()
    return RunConfig(data=data, test_user=args.test_user, encoder=encoder, optim=optim,
                     train=train, held_out_users=args.hold_out)


def _schedule_from_args(args: argparse.Namespace,
                        optim: OptimConfig) -> tuple[OptimConfig, bool]:
    """The schedule the options ask for, and whether it keeps ``optim``'s length in epochs
    (then ``optim``'s decay start and evaluation points still apply; otherwise the decay starts
    after 2/3 of the length unless ``--decay-start`` says otherwise, or never for a constant
    ``optim``, a temporal-convolution encoder's)."""
    if args.sweeps is not None:
        unit, total = "sweeps", args.sweeps
    else:
        unit, total = "epochs", optim.total if args.epochs is None else args.epochs
    default_length = unit == "epochs" and total == optim.total
    constant = optim.decay_start >= optim.total          # a schedule without decay keeps none
    decay_start = args.decay_start if args.decay_start is not None else (
        optim.decay_start if default_length else total if constant else (2 * total) // 3)
    schedule = OptimConfig(learning_rate=args.lr, momentum=args.momentum,
                           clip_norm=args.clip_norm, optimizer=optim.optimizer, unit=unit,
                           total=total,
                           decay_start=decay_start, decay_every=args.decay_every,
                           decay_factor=args.decay_factor)
    return schedule, default_length
