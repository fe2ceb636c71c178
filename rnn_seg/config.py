"""The engine's configuration: encoder shape, optimiser schedule, training run.

Plain frozen dataclasses without TensorFlow, so that command lines (their ``--help`` defaults),
grids and tables read them without loading it; ``lstm``, ``optim`` and ``trainer`` use them and
export them under their old names.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

ResetMode = Literal["original", "corrected"]
RESET_MODES = ("original", "corrected")
Precision = Literal["fp32", "bf16"]
PRECISIONS = ("fp32", "bf16")


@dataclass(frozen=True)
class EncoderConfig:
    """Shape of the recurrent encoder."""

    hidden: int = 1024
    layers: int = 1
    bidirectional: bool = True
    keep_prob: float = 0.5          # dropout keep probability on each layer's inputs and outputs
    init_scale: float = 0.1
    reset_mode: ResetMode = "original"
    precision: Precision = "fp32"   # of the LSTM's matrix products (rnn_seg.lstm's docstring)

    def __post_init__(self):
        if self.reset_mode not in RESET_MODES:
            raise ValueError(f"reset_mode must be one of {RESET_MODES}, not {self.reset_mode!r}")
        if self.precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}, not {self.precision!r}")

    @property
    def output_size(self) -> int:
        return self.hidden * (2 if self.bidirectional else 1)


Unit = Literal["epochs", "sweeps"]
UNITS = ("epochs", "sweeps")


@dataclass(frozen=True)
class OptimConfig:
    """Optimiser and schedule: constant ``learning_rate`` for ``decay_start`` units, then multiplied
    by ``decay_factor`` every ``decay_every`` units, until ``total`` units."""

    learning_rate: float = 1.0
    momentum: float = 0.0
    clip_norm: float = 1.0
    unit: Unit = "epochs"
    total: int = 120
    decay_start: int = 80
    decay_every: int = 40
    decay_factor: float = 0.5

    def __post_init__(self):
        if self.unit not in UNITS:
            raise ValueError(f"unit must be one of {UNITS}, not {self.unit!r}")
        if min(self.total, self.decay_every) < 1 or self.decay_start < 0:
            raise ValueError("total and decay_every must be >= 1, decay_start >= 0")

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


@dataclass(frozen=True)
class TrainConfig:
    """Batching, seeding and what a run writes."""

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
