"""SGD (optionally with momentum), global-norm clipping and a staircase learning-rate schedule.

Schedule lengths are counted in explicit units: ``"sweeps"`` (optimisation steps) or ``"epochs"``
(``ceil(train sequences / batch size)`` sweeps each).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import tensorflow as tf

from .validation import require_choice, require_number

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
        require_number("OptimConfig.learning_rate", self.learning_rate, low=0, open_low=True)
        require_number("OptimConfig.momentum", self.momentum, low=0, high=1, open_high=True)
        require_number("OptimConfig.clip_norm", self.clip_norm, low=0, open_low=True)
        require_choice("OptimConfig.unit", self.unit, UNITS)
        require_number("OptimConfig.total", self.total, integer=True, low=1)
        require_number("OptimConfig.decay_start", self.decay_start, integer=True, low=0)
        require_number("OptimConfig.decay_every", self.decay_every, integer=True, low=1)
        require_number("OptimConfig.decay_factor", self.decay_factor, low=0, high=1,
                       open_low=True)

    def sweeps(self, units: int, sweeps_per_epoch: int) -> int:
        """Convert a count in this schedule's unit to sweeps."""
        return units * (sweeps_per_epoch if self.unit == "epochs" else 1)

    def learning_rate_at(self, sweep: int, sweeps_per_epoch: int) -> float:
        """Learning rate of 0-based sweep ``sweep``."""
        unit = sweep // sweeps_per_epoch if self.unit == "epochs" else sweep
        decays = 0 if unit < self.decay_start else 1 + (unit - self.decay_start) // self.decay_every
        return self.learning_rate * self.decay_factor ** decays


class SGD(tf.Module):
    """``v <- momentum * v + g;  w <- w - lr * v`` after clipping all gradients to one global norm."""

    def __init__(self, variables: Sequence[tf.Variable], momentum: float, clip_norm: float):
        super().__init__(name="sgd")
        self.momentum = momentum
        self.clip_norm = clip_norm
        self.velocities = [tf.Variable(tf.zeros_like(v), trainable=False, name="velocity")
                           for v in variables] if momentum else []

    def apply(self, grads: Sequence[tf.Tensor], variables: Sequence[tf.Variable],
              learning_rate: tf.Tensor) -> tf.Tensor:
        """Update ``variables`` in place; returns the global norm before clipping."""
        clipped, norm = tf.clip_by_global_norm(grads, self.clip_norm)
        if self.momentum:
            for v, g, var in zip(self.velocities, clipped, variables):
                v.assign(self.momentum * v + g)
                var.assign_sub(learning_rate * v)
        else:
            for g, var in zip(clipped, variables):
                var.assign_sub(learning_rate * g)
        return norm
