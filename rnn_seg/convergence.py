"""Has a run's training loss stopped falling? A diagnostic computed from its loss history.

For each task, a least-squares line is fitted to the logarithm of the per-unit training loss
over the last ``window`` fraction of the schedule (20 %: after the learning-rate halving of the
paper's schedule shape, and long enough to average out the 5-10 % unit-to-unit noise of dropout
and batching); ``loss_drop`` is the relative decrease that line implies over the last
``horizon`` fraction (10 %) of the schedule, ``1 - exp(slope * horizon * total)``. A run has
converged when every task's ``loss_drop`` is below ``tolerance`` (5 %): its training loss falls
by less than 5 % over its final tenth. The thresholds are fixed here, before any preset was
measured against them (docs/REPRODUCTION.md).

``loss_drop`` is itself an estimate: ``loss_drop_se`` is its standard error, from the slope's
least-squares standard error (delta method), treating the unit-to-unit noise as independent.
So every run is judged three ways (``verdict``), from each task's 95 % interval of ``loss_drop``
(the slope's normal interval, ``slope +- 1.96 se``, carried through ``1 - exp(slope * span)``):
*converged* when every task's interval lies below the tolerance, *still falling* when some task's
lies above it, *undecided* otherwise. The point verdict (``converged``: every point value below the
tolerance) is kept beside it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

MIN_POINTS = 4
#: The three-way verdicts (``verdict``).
VERDICTS = ("converged", "undecided", "still falling")
#: The normal quantile of the verdict's two-sided 95 % interval.
_Z_95 = 1.959963984540054


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
    fit = loss_drop_fit(units, losses, total, criterion)
    return None if fit is None else fit[0]


def loss_drop_fit(units: np.ndarray, losses: np.ndarray, total: float,
                  criterion: ConvergenceCriterion = ConvergenceCriterion()
                  ) -> tuple[float, float] | None:
    """``loss_drop`` and its standard error, or None (arguments as ``loss_drop``)."""
    units, losses = np.asarray(units, float), np.asarray(losses, float)
    keep = (units > total * (1 - criterion.window)) & np.isfinite(losses) & (losses > 0)
    if keep.sum() < MIN_POINTS:
        return None
    x, y = units[keep], np.log(losses[keep])
    dx = x - x.mean()
    slope = float(dx @ (y - y.mean()) / (dx @ dx))
    residuals = y - y.mean() - slope * dx
    slope_se = np.sqrt(residuals @ residuals / (len(x) - 2) / (dx @ dx))
    span = criterion.horizon * total
    kept = np.exp(slope * span)
    return float(1.0 - kept), float(kept * span * slope_se)


def drop_interval(drop: float, se: float, z: float = _Z_95) -> tuple[float, float]:
    """The interval of a ``loss_drop`` with standard error ``se`` (``loss_drop_fit``): the
    slope's ``+- z`` standard errors carried to the drop. ``se / (1 - drop)`` is the slope's
    standard error times the horizon, so the interval needs nothing but the two numbers."""
    kept = 1.0 - drop
    spread = z * se / kept
    return 1.0 - kept * np.exp(spread), 1.0 - kept * np.exp(-spread)


def verdict(fits: Sequence[tuple[float, float]], tolerance: float) -> str:
    """``converged``, ``still falling`` or ``undecided`` (module docstring) from every task's
    ``(loss_drop, loss_drop_se)``."""
    intervals = [drop_interval(drop, se) for drop, se in fits]
    if any(low > tolerance for low, _ in intervals):
        return "still falling"
    if all(high < tolerance for _, high in intervals):
        return "converged"
    return "undecided"


def convergence(units: np.ndarray, losses: dict[str, np.ndarray], total: float,
                criterion: ConvergenceCriterion = ConvergenceCriterion()) -> dict:
    """Every task's ``loss_drop`` and whether all are below the tolerance.

    Args:
        units: ``[N]`` position of each loss in the schedule's unit (e.g. epoch 1..total).
        losses: per task name, ``[N]`` training loss of each unit.
        total: length of the schedule, in the same unit.
        criterion: window, horizon and tolerance.

    Returns:
        ``{"loss_drop": {task: drop}, "loss_drop_se": {task: se}, "max_loss_drop": worst,
        "max_loss_drop_se": its se, "converged": bool | None, "verdict": str | None,
        "criterion": {...}}``; ``worst``, its se, ``converged`` and ``verdict`` (``VERDICTS``)
        are None when a task has too few units.
    """
    fits = {task: loss_drop_fit(units, values, total, criterion)
            for task, values in losses.items()}
    known = {task: fit for task, fit in fits.items() if fit is not None}
    worst = max(known, key=lambda task: known[task][0]) if len(known) == len(fits) else None
    return {"loss_drop": {task: None if fit is None else fit[0] for task, fit in fits.items()},
            "loss_drop_se": {task: None if fit is None else fit[1] for task, fit in fits.items()},
            "max_loss_drop": None if worst is None else known[worst][0],
            "max_loss_drop_se": None if worst is None else known[worst][1],
            "converged": None if worst is None else bool(known[worst][0] < criterion.tolerance),
            "verdict": None if worst is None else verdict(list(known.values()),
                                                          criterion.tolerance),
            "criterion": {"window": criterion.window, "horizon": criterion.horizon,
                          "tolerance": criterion.tolerance}}


def history_convergence(history: pd.DataFrame, task_names: Sequence[str], total: float,
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
