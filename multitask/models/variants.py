"""The paper's model variants, one registry, identical shared hyperparameters.

A = gestures only (model A); APr / APc / APoc = gestures + progress by regression, classification,
ordered classification; Pr / Pc / Poc = progress only. Optimiser defaults are the paper's.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from jigsaws_tools.task_definition import SUTURING, TaskDefinition
from rnn_seg.config import OptimConfig, TrainConfig
from rnn_seg.encoders.config import SCHEDULES

from .config import WEIGHTINGS, GradNormConfig, HeadConfig

if TYPE_CHECKING:
    from rnn_seg.tasks import Task

#: Paper: APr "GD with Momentum 0.9 ... initial learning rate 0.1"; APc/APoc "GD ... 1.0";
#: decay 0.5 after 80 epochs, stop after 120, evaluate after 100, 110, 120.
_MULTITASK = {"r": OptimConfig(learning_rate=0.1, momentum=0.9),
              "c": OptimConfig(learning_rate=1.0), "oc": OptimConfig(learning_rate=1.0)}
MULTITASK_EVAL = TrainConfig.eval_points
#: How each progress head learns, as the model's full name says it (``Variant.full_name``).
PROGRESS_HEADS = {"r": "regression", "c": "classification", "oc": "ordered classification"}
#: Footnote: single-task P models "were trained ... with the same hyperparameters as their
#: multi-task counterpart. Weight decay was however anticipated and training was stopped after 80
#: iterations." We shift the whole schedule 40 epochs earlier (docs/REPRODUCTION.md).
SINGLE_TASK_SHIFT = 40


@dataclass(frozen=True)
class Variant:
    name: str
    gestures: bool
    progress: str | None        # "r", "c", "oc" or None

    def tasks(self, task: TaskDefinition = SUTURING, heads: HeadConfig = HeadConfig()
              ) -> list[Task]:
        """The heads this variant trains on ``task``: its gestures and / or its progress stages,
        the progress loss configured by ``heads`` (imports TensorFlow, the registry does not)."""
        from baseline.builder import gesture_task

        from .heads import OrdinalProgress, ProgressClassification, ProgressRegression

        tasks = [gesture_task(task)] if self.gestures else []
        if self.progress == "r":
            tasks.append(ProgressRegression(task.stage_names))
        elif self.progress == "c":
            tasks.append(ProgressClassification(task.stage_names))
        elif self.progress == "oc":
            tasks.append(OrdinalProgress(task.stage_names, heads.ordinal_loss))
        return tasks

    @property
    def task_names(self) -> tuple[str, ...]:
        """The names of ``tasks``' heads, as config.json records them (no TensorFlow)."""
        return ("gesture",) * self.gestures + ("progress",) * (self.progress is not None)

    @property
    def multitask(self) -> bool:
        """Whether the variant has two tasks (gestures and progress)."""
        return self.gestures and self.progress is not None

    def full_name(self, weighting: str, gradnorm: GradNormConfig | None = None,
                  weighting_given: bool = True) -> str:
        """The model as a training's first printed line names it, its task weighting included,
        e.g. ``APoc (gestures + progress by ordered classification), GradNorm task weights
        (alpha 1.5)``; with ``weighting_given`` False (the default weighting, not asked for) a
        fixed-weight multi-task model says how to get the paper's GradNorm."""
        head = PROGRESS_HEADS.get(self.progress)
        if not self.multitask:
            return f"{self.name} (gestures only)" if self.gestures else (
                f"{self.name} (progress only, by {head})")
        name = f"{self.name} (gestures + progress by {head})"
        if weighting == "gradnorm":
            gradnorm = gradnorm or GradNormConfig()
            return (f"{name}, GradNorm task weights (alpha {gradnorm.alpha:g}, weight learning "
                    f"rate {gradnorm.learning_rate:g}, {gradnorm.relative_rate} ratios)")
        fixed = f"{name}, fixed task weights w1 = w2 = 1"
        return fixed if weighting_given else (f"{fixed} (the default; --weighting gradnorm for "
                                              "the paper's GradNorm)")

    def optim(self, encoder: str = "lstm") -> OptimConfig:
        """The paper's optimiser and schedule for this variant on the LSTM (and on a user's
        encoder, named by its import path); on a temporal convolutional ``encoder``, that
        encoder's reference one, the same for every variant
        (``rnn_seg.encoders.config.SCHEDULES``, docs/REPRODUCTION.md)."""
        if encoder in SCHEDULES:
            return SCHEDULES[encoder].optim
        base = _MULTITASK[self.progress] if self.progress else OptimConfig()
        if self.gestures:
            return base
        return replace(base, total=base.total - SINGLE_TASK_SHIFT,
                       decay_start=base.decay_start - SINGLE_TASK_SHIFT)

    def eval_points(self, encoder: str = "lstm") -> tuple[int, ...]:
        """The evaluation epochs of ``optim(encoder)``."""
        if encoder in SCHEDULES:
            return SCHEDULES[encoder].eval_points
        shift = 0 if self.gestures else SINGLE_TASK_SHIFT
        return tuple(p - shift for p in MULTITASK_EVAL)

    def schedule(self, scale: float = 1.0, encoder: str = "lstm"
                 ) -> tuple[OptimConfig, tuple[int, ...]]:
        """The optimiser and evaluation epochs (``optim``, ``eval_points``) with every epoch
        count (length, decay start and interval, evaluation points) multiplied by ``scale`` and
        rounded half up."""
        optim, points = self.optim(encoder), self.eval_points(encoder)
        if scale == 1.0:
            return optim, points

        def scaled(epochs: int) -> int:
            return max(1, int(epochs * scale + 0.5))
        optim = replace(optim, total=scaled(optim.total), decay_start=scaled(optim.decay_start),
                        decay_every=scaled(optim.decay_every))
        return optim, tuple(sorted({min(scaled(p), optim.total) for p in points}))


VARIANTS: dict[str, Variant] = {v.name: v for v in (
    Variant("A", True, None),
    Variant("APr", True, "r"), Variant("APc", True, "c"), Variant("APoc", True, "oc"),
    Variant("Pr", False, "r"), Variant("Pc", False, "c"), Variant("Poc", False, "oc"),
)}


def check_weighting(variant: Variant, weighting: str) -> None:
    """Raise ``ValueError`` unless ``variant`` has ``weighting`` (GradNorm needs two tasks)."""
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting must be one of {WEIGHTINGS}, not {weighting!r}")
    if weighting == "gradnorm" and not variant.multitask:
        raise ValueError(f"GradNorm needs two tasks; variant {variant.name} has one")


def get_variant(name: str) -> Variant:
    try:
        return VARIANTS[name]
    except KeyError:
        raise ValueError(f"unknown variant {name!r}; choose one of {', '.join(VARIANTS)}") from None


def batch_size(encoder: str = "lstm") -> int:
    """Sequences per sweep: DiPietro's 5 for the LSTM (and a user's encoder), the reference's
    for a TCN."""
    return SCHEDULES[encoder].batch_size if encoder in SCHEDULES else TrainConfig.batch_size
