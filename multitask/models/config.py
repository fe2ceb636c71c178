"""The multi-task configuration: how a run weights its task losses (fixed w1 = w2 = 1, or
GradNorm), GradNorm's settings and the progress heads' loss. Free of TensorFlow, so that command
lines and the grid read it without loading it; ``gradnorm.GradNormTrainer`` trains with it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from rnn_seg.validation import require_choice, require_number

Weighting = Literal["fixed", "gradnorm"]
WEIGHTINGS = ("fixed", "gradnorm")
RelativeRate = Literal["chen", "paper"]
RELATIVE_RATES = ("chen", "paper")
OrdinalLoss = Literal["sum", "mean"]
ORDINAL_LOSSES = ("sum", "mean")


@dataclass(frozen=True)
class GradNormConfig:
    """GradNorm's asymmetry ``alpha`` (0 = equal gradient norms), the task weights' learning rate,
    and what the loss ratios ``L_i / L_i(0)`` are divided by: their mean (``chen``) or the mean
    loss (``paper``)."""

    alpha: float = 1.5
    learning_rate: float = 0.025
    relative_rate: RelativeRate = "chen"

    def __post_init__(self):
        require_number("GradNormConfig.alpha", self.alpha, low=0)
        require_number("GradNormConfig.learning_rate", self.learning_rate, low=0, open_low=True)
        require_choice("GradNormConfig.relative_rate", self.relative_rate, RELATIVE_RATES)


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
        require_choice("HeadConfig.ordinal_loss", self.ordinal_loss, ORDINAL_LOSSES)


@dataclass(frozen=True)
class SelectionConfig:
    """Settings chosen per outer fold on that fold's training users alone (a nested selection,
    e.g. ``results/tcn/PLAN_factors.md``, section D.2), recorded by every run of a grid whose
    spec sets ``fold_settings`` (``multitask.grid.spec``), so that tables pool the runs of its
    folds as one configuration: the procedure that chose each fold's settings
    (``multitask.evidence.runs.pooling``).

    Settings are named as in a run's recorded settings (``rnn_seg.runs.settings``, e.g.
    ``run.encoder.kernel``; a default that config.json leaves out is None).

    ``per_fold``: outer fold -> each selected setting -> its value on that fold;
    ``common``: each selected setting -> its value on the folds ``per_fold`` does not name;
    ``common_fingerprint``: the data fingerprint at ``common`` (what a run of the same release
    without the selection records).
    """

    per_fold: dict[str, dict[str, Any]]
    common: dict[str, Any]
    common_fingerprint: str

    def __post_init__(self):
        for fold, values in self.per_fold.items():
            if not isinstance(values, dict) or set(values) != set(self.common):
                raise ValueError(f"SelectionConfig.per_fold.{fold}: expected the settings "
                                 f"{', '.join(sorted(self.common))} (got {values!r})")

    def expected(self, outer: str) -> dict[str, Any]:
        """The selected settings of outer fold ``outer``."""
        return self.per_fold.get(outer, self.common)
