"""The multi-task configuration: how a run weights its task losses (fixed w1 = w2 = 1, or
GradNorm), GradNorm's settings and the progress heads' loss. Free of TensorFlow, so that command lines and the grid read it
without loading it; ``gradnorm.GradNormTrainer`` trains with it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Weighting = Literal["fixed", "gradnorm"]
WEIGHTINGS = ("fixed", "gradnorm")
RelativeRate = Literal["chen", "paper"]
RELATIVE_RATES = ("chen", "paper")
OrdinalLoss = Literal["sum", "mean"]
ORDINAL_LOSSES = ("sum", "mean")


@dataclass(frozen=True)
class GradNormConfig:
    """GradNorm's asymmetry ``alpha``, the task weights' learning rate, and what the loss ratios
    ``L_i / L_i(0)`` are divided by: their mean (``chen``) or the mean loss (``paper``)."""

    alpha: float = 1.5
    learning_rate: float = 0.025
    relative_rate: RelativeRate = "chen"

    def __post_init__(self):
        if self.relative_rate not in RELATIVE_RATES:
            raise ValueError(f"relative_rate must be one of {RELATIVE_RATES}, "
                             f"not {self.relative_rate!r}")


@dataclass(frozen=True)
class HeadConfig:
    """How the progress heads score their outputs.

    ``ordinal_loss``: the ordered head's binary cross-entropy ``sum``-med over its outputs, one
    per stage (the paper's MCE, Eq. 2, with sigmoid outputs: "MBCE") or averaged over them
    (``mean``, our earlier reading: for Suturing's 5 stages a 5x smaller gradient); either way
    averaged over time steps.
    """

    ordinal_loss: OrdinalLoss = "sum"

    def __post_init__(self):
        if self.ordinal_loss not in ORDINAL_LOSSES:
            raise ValueError(f"ordinal_loss must be one of {ORDINAL_LOSSES}, "
                             f"not {self.ordinal_loss!r}")
