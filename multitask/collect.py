"""Gather a grid's finished runs into tables: one row per run, per fold, per configuration.

Only runs with ``finished.json`` count; half-written runs are ignored (and reported).
Metric columns are ``<task>_<metric>``: ``gesture_accuracy``, ``gesture_edit``,
``gesture_f1@10``, ``gesture_accuracy_G1`` ..., ``progress_accuracy``, ``progress_edit``,
``progress_f1@10``, ``progress_mae`` (normalised MAE of the regression output rounded to the
nearest stage and clipped, in % of the stage range: the 4-stage span for Suturing, the paper's
metric) and ``progress_mae_raw`` (the same of the raw output). Each run's value is the mean over
its evaluation points. Each run also has ``converged`` and ``loss_drop``
(``rnn_seg.convergence``: the relative fall of its training loss over the last 10 % of its
schedule).
"""
from __future__ import annotations

import json
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np
import pandas as pd

from jigsaws_tools.task_definition import PAPER_TASK
from rnn_seg.rundir import is_finished

from .grid_spec import RunKey

KEY_COLUMNS = [f.name for f in fields(RunKey)]
CONFIG_COLUMNS = ["annotations", "direction", "variant", "weighting"]
#: The paper's metrics, in its table order.
METRICS = ["gesture_accuracy", "gesture_edit", "gesture_f1@10", "progress_mae",
           "progress_mae_raw", "progress_accuracy", "progress_edit", "progress_f1@10"]
LOWER_IS_BETTER = {"progress_mae", "progress_mae_raw"}
_RENAME = {"mae_normalised_rounded": "mae", "mae_normalised": "mae_raw"}
#: Per-run columns that are not metrics (not averaged over seeds).
CONVERGENCE_COLUMNS = ["converged", "loss_drop"]


def key_from_path(run_dir: Path, root: Path) -> RunKey:
    """Inverse of ``RunKey.path``: ``runs/<annotations>/<direction>/<variant>-<weighting>/seed<k>/<fold>``."""
    annotations, direction, config, seed, fold = run_dir.relative_to(root / "runs").parts
    variant, weighting = config.rsplit("-", 1)
    return RunKey(annotations, direction, variant, weighting, int(seed.removeprefix("seed")), fold)


def run_rows(grid_dir: Path | str) -> tuple[pd.DataFrame, list[Path]]:
    """One row per finished run (key columns + metrics); also the unfinished run folders."""
    root = Path(grid_dir)
    rows, unfinished = [], []
    for metrics_dir in sorted((root / "runs").glob("*/*/*/seed*/*")):
        if not is_finished(metrics_dir):
            unfinished.append(metrics_dir)
            continue
        key = key_from_path(metrics_dir, root)
        metrics = json.loads((metrics_dir / "metrics.json").read_text())
        row = asdict(key)
        convergence = metrics.get("convergence", {})
        row.update(converged=convergence.get("converged"),
                   loss_drop=convergence.get("max_loss_drop"))
        for task, values in metrics["mean"].items():
            row.update({f"{task}_{_RENAME.get(k, k)}": v for k, v in values.items()})
        rows.append(row)
    if not rows:
        raise ValueError(f"{root}: no finished runs under {root / 'runs'}")
    return pd.DataFrame(rows), unfinished


def grid_task_name(grid_dir: Path | str) -> str:
    """The task a grid's runs were trained on (their ``config.json``); runs written before tasks
    existed are Suturing's."""
    for config in sorted(Path(grid_dir).glob("runs/*/*/*/seed*/*/config.json")):
        data = json.loads(config.read_text())["run"]["data"]
        return data.get("task", {}).get("name", PAPER_TASK)
    return PAPER_TASK


def per_fold(runs: pd.DataFrame) -> pd.DataFrame:
    """Mean over seeds for every configuration and fold (the numbers the tables summarise), with
    ``seeds`` and ``unconverged`` (runs whose training loss was still falling) per fold."""
    metric_cols = [c for c in runs.columns if c not in KEY_COLUMNS + CONVERGENCE_COLUMNS]
    grouped = runs.groupby(CONFIG_COLUMNS + ["fold"], sort=True)
    table = grouped[metric_cols].mean()
    table.insert(0, "unconverged", grouped["converged"].agg(lambda c: int((c == False).sum())))  # noqa: E712
    table.insert(0, "seeds", grouped.size())
    return table.reset_index()


def summary(folds: pd.DataFrame) -> pd.DataFrame:
    """Mean and sample standard deviation over folds: columns ``<metric>_mean``, ``<metric>_std``,
    plus ``folds`` (how many folds each configuration has) and ``unconverged`` (its runs whose
    training loss was still falling)."""
    counts = ["fold", "seeds", "unconverged"]
    metric_cols = [c for c in folds.columns if c not in CONFIG_COLUMNS + counts]
    grouped = folds.groupby(CONFIG_COLUMNS, sort=True)
    mean = grouped[metric_cols].mean().add_suffix("_mean")
    std = grouped[metric_cols].std(ddof=1).add_suffix("_std")
    table = pd.concat([mean, std], axis=1)
    table.insert(0, "unconverged", grouped["unconverged"].sum())
    table.insert(0, "folds", grouped.size())
    return table.reset_index()


def lookup(summary_table: pd.DataFrame, annotations: str, direction: str, config: str
           ) -> pd.Series | None:
    """The summary row of one configuration, or None if the grid did not run it."""
    variant, weighting = config.rsplit("-", 1)
    rows = summary_table[(summary_table.annotations == annotations)
                         & (summary_table.direction == direction)
                         & (summary_table.variant == variant)
                         & (summary_table.weighting == weighting)]
    return rows.iloc[0] if len(rows) else None


def finite(value) -> float | None:
    """``value`` as a float, or None for missing / NaN."""
    if value is None:
        return None
    value = float(value)
    return None if np.isnan(value) else value
