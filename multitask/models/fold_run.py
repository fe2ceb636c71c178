"""Train one variant on one LOUO fold, with fixed loss weights or GradNorm."""
from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Callable

from baseline.builder import build_trainer
from baseline.config import RunConfig
from jigsaws_tools.dataset import Dataset
from rnn_seg.trainer import Trainer

from .config import SelectionConfig, Weighting
from .gradnorm import GradNormConfig, GradNormTrainer
from .heads import HeadConfig
from .run_record import variant_extra
from .variants import Variant


def variant_trainer(variant: Variant, weighting: Weighting, config: RunConfig, run_dir: Path,
                    gradnorm: GradNormConfig = GradNormConfig(), dataset: Dataset | None = None,
                    log: Callable[[str], None] = print, heads: HeadConfig = HeadConfig(),
                    selection: SelectionConfig | None = None) -> Trainer:
    """A ready trainer of ``variant`` on ``run_dir``'s fold.

    Args:
        variant: the model variant.
        weighting: ``"fixed"``, w1 = w2 = 1 (the baseline's trainer, unchanged), or
            ``"gradnorm"``, the GradNorm trainer.
        config: the run's configuration.
        run_dir: the run folder.
        gradnorm: GradNorm's settings (with ``"gradnorm"``).
        dataset: ``config.data``'s dataset, already loaded; None = load it.
        log: where progress lines go.
        heads: the progress head's loss.
        selection: the nested selection the run is part of, recorded (None: none).
    """
    extra = variant_extra(variant, weighting, gradnorm, heads, selection)
    trainer = partial(GradNormTrainer, gradnorm=gradnorm) if weighting == "gradnorm" else Trainer
    return build_trainer(config, variant.tasks(config.data.task, heads), run_dir, dataset,
                         trainer=trainer, extra_configs=extra, log=log)


def train_variant(variant: Variant, weighting: Weighting, config: RunConfig, run_dir: Path,
                  gradnorm: GradNormConfig = GradNormConfig(), dataset: Dataset | None = None,
                  log: Callable[[str], None] = print, heads: HeadConfig = HeadConfig(),
                  restart: bool = False) -> dict:
    """Train ``variant`` on one fold.

    Args:
        variant: the model variant.
        weighting: ``"fixed"`` or ``"gradnorm"`` (``variant_trainer``).
        config: the run's configuration.
        run_dir: the run folder; an unfinished run there resumes.
        gradnorm: GradNorm's settings (with ``"gradnorm"``).
        dataset: ``config.data``'s dataset, already loaded; None = load it.
        log: where progress lines go.
        heads: the progress head's loss.
        restart: delete a previous run's config and results in ``run_dir`` first.

    Returns:
        The run's metrics (``metrics.json``'s content).
    """
    return variant_trainer(variant, weighting, config, run_dir, gradnorm, dataset, log,
                           heads).run(restart)
