"""The engine's configuration: encoder shape, optimiser schedule, training run.

Plain frozen dataclasses without TensorFlow, so that command lines (their ``--help`` defaults),
grids and tables read them without loading it; ``lstm``, ``optim`` and ``trainer`` use them and
export them under their old names.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import ClassVar, Literal, Sequence

from .validation import require_bool, require_choice, require_number

ResetMode = Literal["original", "corrected"]
RESET_MODES = ("original", "corrected")
Precision = Literal["fp32", "bf16"]
PRECISIONS = ("fp32", "bf16")
Loops = Literal["auto", "graph", "xla", "fused"]
LOOPS = ("auto", "graph", "xla", "fused")
#: The loops a process runs: ``auto`` is ``fused`` where ``rnn_seg.kernels`` builds and loads,
#: else ``graph`` (``rnn_seg.lstm.runnable_loops``).
RUNNABLE_LOOPS = ("graph", "xla", "fused")


@dataclass(frozen=True)
class EncoderConfig:
    """Shape of the recurrent encoder, and how its recurrent loops run."""

    #: How the loops run, not what they compute (``rnn_seg.lstm``'s docstring): left out of the
    #: settings a run folder is checked against (``rnn_seg.runs.settings``), like the thread plan.
    output_fields: ClassVar[tuple[str, ...]] = ("loops",)
    #: Not recorded while it holds its default (``rnn_seg.runs.folder.to_jsonable``): runs written
    #: before other encoders existed keep their settings; a record without it is an LSTM's.
    unrecorded_defaults: ClassVar[tuple[str, ...]] = ("kind",)

    kind: Literal["lstm"] = "lstm"  # the encoder (rnn_seg.encoders); TCNs have their own configs
    hidden: int = 1024
    layers: int = 1
    bidirectional: bool = True
    keep_prob: float = 0.5          # dropout keep probability on each layer's inputs and outputs
    init_scale: float = 0.1
    reset_mode: ResetMode = "original"
    precision: Precision = "fp32"   # of the LSTM's matrix products (rnn_seg.lstm's docstring)
    loops: Loops = "auto"           # TensorFlow ops step by step ("graph"), one XLA kernel per
                                    # loop ("xla"), the compiled C++ loops of rnn_seg.kernels
                                    # ("fused"), or "auto": fused where they build, else graph

    def __post_init__(self):
        require_choice("EncoderConfig.kind", self.kind, ("lstm",))
        require_number("EncoderConfig.hidden", self.hidden, integer=True, low=1)
        require_number("EncoderConfig.layers", self.layers, integer=True, low=1)
        require_bool("EncoderConfig.bidirectional", self.bidirectional)
        require_number("EncoderConfig.keep_prob", self.keep_prob, low=0, high=1, open_low=True)
        require_number("EncoderConfig.init_scale", self.init_scale, low=0, open_low=True)
        require_choice("EncoderConfig.reset_mode", self.reset_mode, RESET_MODES)
        require_choice("EncoderConfig.precision", self.precision, PRECISIONS)
        require_choice("EncoderConfig.loops", self.loops, LOOPS)

    @property
    def output_size(self) -> int:
        return self.hidden * (2 if self.bidirectional else 1)


Unit = Literal["epochs", "sweeps"]
UNITS = ("epochs", "sweeps")
Optimizer = Literal["sgd", "rmsprop", "adam"]
OPTIMIZERS = ("sgd", "rmsprop", "adam")


def unit_name(unit: Unit) -> str:
    """One of a unit, as a label reads it: ``"epochs"`` -> ``"epoch"``."""
    return {"epochs": "epoch", "sweeps": "sweep"}[unit]


@dataclass(frozen=True)
class OptimConfig:
    """Optimiser and schedule: constant ``learning_rate`` for ``decay_start`` units, then multiplied
    by ``decay_factor`` every ``decay_every`` units, until ``total`` units. ``optimizer``: SGD (with
    ``momentum``; the paper's), or RMSprop / Adam with their references' constants
    (``rnn_seg.optim``); ``clip_norm`` 0 = no clipping."""

    #: Not recorded while it holds its default (``rnn_seg.runs.folder.to_jsonable``), so the
    #: records of runs written before it existed stay the same.
    unrecorded_defaults: ClassVar[tuple[str, ...]] = ("optimizer",)

    learning_rate: float = 1.0
    momentum: float = 0.0
    clip_norm: float = 1.0
    optimizer: Optimizer = "sgd"
    unit: Unit = "epochs"
    total: int = 120
    decay_start: int = 80
    decay_every: int = 40
    decay_factor: float = 0.5

    def __post_init__(self):
        require_number("OptimConfig.learning_rate", self.learning_rate, low=0, open_low=True)
        require_number("OptimConfig.momentum", self.momentum, low=0, high=1, open_high=True)
        require_number("OptimConfig.clip_norm", self.clip_norm, low=0)
        require_choice("OptimConfig.optimizer", self.optimizer, OPTIMIZERS)
        if self.momentum and self.optimizer != "sgd":
            raise ValueError(f"OptimConfig.momentum applies to sgd, not {self.optimizer} (got "
                             f"{self.momentum!r})")
        require_choice("OptimConfig.unit", self.unit, UNITS)
        require_number("OptimConfig.total", self.total, integer=True, low=1)
        require_number("OptimConfig.decay_start", self.decay_start, integer=True, low=0)
        require_number("OptimConfig.decay_every", self.decay_every, integer=True, low=1)
        require_number("OptimConfig.decay_factor", self.decay_factor, low=0, high=1,
                       open_low=True)

    @property
    def unit_name(self) -> str:
        """The schedule's unit in the singular, for labels (``"epoch"``)."""
        return unit_name(self.unit)

    def sweeps(self, units: int, sweeps_per_epoch: int) -> int:
        """Convert a count in this schedule's unit to sweeps."""
        return units * (sweeps_per_epoch if self.unit == "epochs" else 1)

    def learning_rate_at(self, sweep: int, sweeps_per_epoch: int) -> float:
        """Learning rate of 0-based sweep ``sweep``."""
        unit = sweep // sweeps_per_epoch if self.unit == "epochs" else sweep
        decays = 0 if unit < self.decay_start else 1 + (unit - self.decay_start) // self.decay_every
        return self.learning_rate * self.decay_factor ** decays


PredictionMode = Literal["sweep", "per_sequence"]
PREDICTION_MODES = ("sweep", "per_sequence")
PlotPoints = Literal["last", "all", "none"]
PLOT_POINTS = ("last", "all", "none")
KeepCheckpoints = Literal["final", "eval_points", "all"]
KEEP_CHECKPOINTS = ("final", "eval_points", "all")


@dataclass(frozen=True)
class TrainConfig:
    """Batching, seeding and what a run writes."""

    #: Fields that change what a run writes, not what it computes: left out of the settings its
    #: folder is checked against (``rnn_seg.runs.settings``), so a run may resume with other values.
    output_fields: ClassVar[tuple[str, ...]] = (
        "log_every", "checkpoint_every", "plots", "keep_checkpoints", "monitor_every",
        "monitor_train", "tensorboard")

    batch_size: int = 5
    seed: int = 0
    eval_points: tuple[int, ...] = (100, 110, 120)   # in the schedule's unit; () = at the end
    prediction: PredictionMode = "sweep"
    log_every: int = 1                               # units between progress lines
    monitor_every: int = 10                          # units between test scores on them
    monitor_train: bool = False                      # also score the training set (slow)
    checkpoint_every: int = 1                        # units between checkpoints
    plots: PlotPoints = "last"                       # evaluation points with per-sequence figures
    tensorboard: bool = False                        # also write progress scalars there
    keep_checkpoints: KeepCheckpoints = "final"  # kept by a finished run (rnn_seg.runs.checkpoints)

    def __post_init__(self):
        require_number("TrainConfig.batch_size", self.batch_size, integer=True, low=1)
        require_number("TrainConfig.seed", self.seed, integer=True, low=0)
        if not isinstance(self.eval_points, tuple):
            raise ValueError(f"TrainConfig.eval_points must be a tuple of integers >= 1 "
                             f"(got {self.eval_points!r})")
        for point in self.eval_points:
            require_number("TrainConfig.eval_points", point, integer=True, low=1)
        if list(self.eval_points) != sorted(set(self.eval_points)):
            raise ValueError(f"TrainConfig.eval_points must increase (got {self.eval_points!r})")
        require_choice("TrainConfig.prediction", self.prediction, PREDICTION_MODES)
        require_number("TrainConfig.log_every", self.log_every, integer=True, low=1)
        require_number("TrainConfig.monitor_every", self.monitor_every, integer=True, low=0)
        require_bool("TrainConfig.monitor_train", self.monitor_train)
        require_number("TrainConfig.checkpoint_every", self.checkpoint_every, integer=True, low=1)
        require_choice("TrainConfig.plots", self.plots, PLOT_POINTS)
        require_bool("TrainConfig.tensorboard", self.tensorboard)
        require_choice("TrainConfig.keep_checkpoints", self.keep_checkpoints, KEEP_CHECKPOINTS)


def check_eval_points(points: Sequence[int], optim: OptimConfig) -> None:
    """Raise unless every evaluation point lies within the schedule (1..``optim.total``)."""
    beyond = [p for p in points if p > optim.total]
    if beyond:
        raise ValueError(f"evaluation point(s) {', '.join(map(str, beyond))} beyond the "
                         f"{optim.total} {optim.unit} of training (TrainConfig.eval_points must "
                         f"lie in 1..OptimConfig.total)")


def require_native_precision(precision: Precision) -> None:
    """Refuse ``bf16`` on a CPU without native bfloat16 arithmetic (TensorFlow would emulate it,
    several times slower than float32)."""
    if precision == "bf16" and not native_bf16():
        raise ValueError("--precision bf16 needs a CPU with native bfloat16 arithmetic "
                         "(x86 AVX512_BF16 or AMX_BF16, or Arm BF16); this one has none: use "
                         "--precision fp32")


@lru_cache(maxsize=1)
def cpu_flags() -> frozenset[str]:
    """The instruction-set flags this CPU reports (Linux ``/proc/cpuinfo``; empty elsewhere)."""
    try:
        return frozenset(Path("/proc/cpuinfo").read_text().split())
    except OSError:
        return frozenset()


def native_bf16() -> bool:
    """Whether this CPU reports native bfloat16 instructions."""
    return bool({"avx512_bf16", "amx_bf16", "bf16"} & cpu_flags())
