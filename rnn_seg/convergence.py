"""Has a run's training loss stopped falling? A diagnostic computed from its loss history.

For each task, a least-squares line is fitted to the logarithm of the per-unit training loss
over the last ``window`` fraction of the schedule (20 %: after the learning-rate halving of the
paper's schedule shape, and long enough to average out the 5-10 % unit-to-unit noise of dropout
and batching); ``loss_drop`` is the relative decrease that line implies over the last
``horizon`` fraction (10 %) of the schedule, ``1 - exp(slope * horizon * total)``. A run has
converged when every task's ``loss_drop`` is below ``tolerance`` (5 %): its training loss falls
by less than 5 % over its final tenth. The thresholds are fixed here, before any preset was
measured against them (docs/REPRODUCTION.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

MIN_POINTS = 4


@dataclass(frozen=True)
class ConvergenceCriterion:
    """Fractions of the schedule and the tolerated relative loss decrease."""

    window: float = 0.2
    horizon: float = 0.1
    tolerance: float = 0.05


def loss_drop(units: np.ndarray, losses: np.ndarray, total: float,
              criterion: ConvergenceCriterion = ConvergenceCriterion()) -> float | None:
    """Relative decrease of the fitted training loss over the schedule's last ``horizon``.

    Args:
        units: ``[N]`` position of each loss in the schedule's unit (e.g. epoch 1..total).
        losses: ``[N]`` training loss of each unit (mean over its sweeps), > 0.
        total: length of the schedule, in the same unit.
        criterion: window, horizon and tolerance.

    Returns:
        The relative decrease (0.1 = the loss falls by 10 %; negative when it rises), or None
        when the window holds fewer than ``MIN_POINTS`` finite losses.
    """
    units, losses = np.asarray(units, float), np.asarray(losses, float)
    keep = (units > total * (1 - criterion.window)) & np.isfinite(losses) & (losses > 0)
    if keep.sum() < MIN_POINTS:
        return None
    slope = np.polyfit(units[keep], np.log(losses[keep]), 1)[0]
    return float(1.0 - np.exp(slope * criterion.horizon * total))


def convergence(units: np.ndarray, losses: dict[str, np.ndarray], total: float,
                criterion: ConvergenceCriterion = ConvergenceCriterion()) -> dict:
    """Every task's ``loss_drop`` and whether all are below the tolerance.

    Args:
        units: ``[N]`` position of each loss in the schedule's unit (e.g. epoch 1..total).
        losses: per task name, ``[N]`` training loss of each unit.
        total: length of the schedule, in the same unit.
        criterion: window, horizon and tolerance.

    Returns:
        ``{"loss_drop": {task: drop}, "max_loss_drop": worst, "converged": bool | None,
        "criterion": {...}}``; ``worst`` and ``converged`` are None when a task has too few units.
    """
    drops = {task: loss_drop(units, values, total, criterion) for task, values in losses.items()}
    known = [d for d in drops.values() if d is not None]
    worst = max(known) if len(known) == len(drops) else None
    return {"loss_drop": drops, "max_loss_drop": worst,
            "converged": None if worst is None else bool(worst < criterion.tolerance),
            "criterion": {"window": criterion.window, "horizon": criterion.horizon,
                          "tolerance": criterion.tolerance}}


def history_convergence(history, task_names: Sequence[str], total: float,
                        criterion: ConvergenceCriterion = ConvergenceCriterion()) -> dict:
    """``convergence`` of a run's ``history.csv`` table.

    Args:
        history: the table as a pandas DataFrame: columns ``n`` (the unit) and ``loss_<task>``.
        task_names: the tasks whose losses are checked.
        total: length of the schedule (``OptimConfig.total``), in ``n``'s unit.
        criterion: window, horizon and tolerance.
    """
    return convergence(history["n"].to_numpy(),
                       {t: history[f"loss_{t}"].to_numpy() for t in task_names}, total, criterion)
