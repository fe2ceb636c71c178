"""Train one variant on one LOUO fold, with fixed loss weights or GradNorm."""
from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Callable

from baseline.config import RunConfig
from baseline.builder import build_trainer
from jigsaws_tools.dataset import Dataset
from rnn_seg.trainer import Trainer

from .config import WEIGHTINGS, Weighting
from .gradnorm import GradNormConfig, GradNormTrainer
from .heads import HeadConfig
from .variants import Variant


def variant_trainer(variant: Variant, weighting: Weighting, config: RunConfig, run_dir: Path,
                    gradnorm: GradNormConfig = GradNormConfig(), dataset: Dataset | None = None,
                    log: Callable[[str], None] = print, heads: HeadConfig = HeadConfig()
                    ) -> Trainer:
    """A ready trainer of ``variant`` on ``run_dir``'s fold; ``fixed`` uses w1 = w2 = 1 (the
    baseline's trainer, unchanged), ``gradnorm`` the GradNorm trainer; ``heads`` configures the
    progress head's loss."""
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting must be one of {WEIGHTINGS}, not {weighting!r}")
    if weighting == "gradnorm" and not variant.multitask:
        raise ValueError(f"GradNorm needs two tasks; variant {variant.name} has one")
    extra = {"variant": variant.name, "weighting": weighting, "heads": heads}
    trainer = Trainer
    if weighting == "gradnorm":
        extra["gradnorm"] = gradnorm
        trainer = partial(GradNormTrainer, gradnorm=gradnorm)
    return build_trainer(config, variant.tasks(config.data.task, heads), run_dir, dataset,
                         trainer=trainer,
                         extra_configs=extra, log=log)


def train_variant(variant: Variant, weighting: Weighting, config: RunConfig, run_dir: Path,
                  gradnorm: GradNormConfig = GradNormConfig(), dataset: Dataset | None = None,
                  log: Callable[[str], None] = print, heads: HeadConfig = HeadConfig()) -> dict:
    """Train ``variant`` on one fold (see ``variant_trainer``); returns the run's metrics."""
    return variant_trainer(variant, weighting, config, run_dir, gradnorm, dataset, log,
                           heads).run()
