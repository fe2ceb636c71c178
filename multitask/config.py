"""The multi-task configuration: how a run weights its task losses (fixed w1 = w2 = 1, or
GradNorm) and GradNorm's settings. Free of TensorFlow, so that command lines and the grid read it
without loading it; ``gradnorm.GradNormTrainer`` trains with it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Weighting = Literal["fixed", "gradnorm"]
WEIGHTINGS = ("fixed", "gradnorm")


@dataclass(frozen=True)
class GradNormConfig:
    """GradNorm's asymmetry ``alpha`` and the learning rate of the task weights (the paper's)."""

    alpha: float = 1.5
    learning_rate: float = 0.025
