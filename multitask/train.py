"""Train one variant on one LOUO fold, with fixed loss weights or GradNorm."""
from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Callable, Literal

from baseline.config import RunConfig
from baseline.model import build_trainer
from jigsaws_tools.dataset import Dataset

from .gradnorm import GradNormConfig, GradNormTrainer
from .variants import Variant

Weighting = Literal["fixed", "gradnorm"]
WEIGHTINGS = ("fixed", "gradnorm")


def train_variant(variant: Variant, weighting: Weighting, config: RunConfig, run_dir: Path,
                  gradnorm: GradNormConfig = GradNormConfig(), dataset: Dataset | None = None,
                  log: Callable[[str], None] = print) -> dict:
    """Train ``variant``; ``fixed`` uses w1 = w2 = 1 (the baseline's trainer, unchanged)."""
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting must be one of {WEIGHTINGS}, not {weighting!r}")
    if weighting == "gradnorm" and not variant.multitask:
        raise ValueError(f"GradNorm needs two tasks; variant {variant.name} has one")
    extra = {"variant": variant.name, "weighting": weighting}
    if weighting == "gradnorm":
        extra["gradnorm"] = gradnorm
        trainer = build_trainer(config, variant.tasks(), run_dir, dataset,
                                trainer=partial(GradNormTrainer, gradnorm=gradnorm),
                                extra_configs=extra, log=log)
    else:
        trainer = build_trainer(config, variant.tasks(), run_dir, dataset, extra_configs=extra,
                                log=log)
    return trainer.run()
