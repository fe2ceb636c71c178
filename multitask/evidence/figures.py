"""The paper's figures from a grid's runs, each saved as PNG and PDF.

* ``per_gesture_accuracy``: accuracy of each gesture, A vs APoc (paper Fig. 4): the mean over the
  folds whose test trials contain the gesture, their standard deviation as error bar; a gesture
  that occurs but is never recognised shows as 0, one absent from every test set as n/a;
* ``segmentation_example``: ground truth, A and APoc ribbons of one test trial (Fig. 5);
* ``progress_example``: true progress and APr's regression output, APc's and APoc's predicted
  stages over time (Fig. 6);
* ``fold_accuracy``: gesture vs progress accuracy of each fold, APoc (Fig. 7; without APoc runs,
  every two-task configuration);
* ``gradnorm_weights``: task weights over training for the GradNorm runs.

Figures read the revised-annotation, bidirectional runs of seed 0 where one run is needed; the
example trial is a choice (``--example-trial``); the two example figures need that trial's
predictions (a scores archive keeps none: ``multitask.grid.archive``). Time is in seconds; class
names come from the per-class accuracy columns of the runs' metrics (``gesture_accuracy_<class>``)
and from the predictions' score columns (``<task>_p_<class>``), colours from ``jigsaws_tools.plots``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from jigsaws_tools.plots import (Ribbon, draw_ribbon, layout_with_legends,  # noqa: E402
                                 task_colours)
from jigsaws_tools.release import KINEMATICS_HZ  # noqa: E402
from jigsaws_tools.task_definition import load_task  # noqa: E402

from ..grid.archive import kept_predictions  # noqa: E402
from ..grid.spec import RunKey  # noqa: E402
from .collect import grid_task_name  # noqa: E402
from .tables import CONFIG_LABELS  # noqa: E402

OFFLINE = {"annotations": "revised", "direction": "bidirectional"}
COMPARED = ("A-fixed", "APoc-fixed", "APoc-gradnorm")
#: Runs shown by the example figures: segmentation, then progress (regression output first).
SEGMENTATION_RUNS = ("A-fixed", "APoc-fixed")
PROGRESS_RUNS = ("APr-fixed", "APc-fixed", "APoc-fixed")
FOLD_RUNS = ("APoc-fixed", "APoc-gradnorm")
#: Every figure ``all_figures`` draws (file names without extension).
FIGURES = ("per_gesture_accuracy", "segmentation_example", "progress_example", "fold_accuracy",
           "gradnorm_weights")


def save(fig: plt.Figure, out_dir: Path, name: str) -> list[Path]:
    """Write ``fig`` as ``<name>.png`` (150 dpi) and ``<name>.pdf`` and close it.

    Args:
        fig: the figure.
        out_dir: the folder written into (created if needed).
        name: the files' name without extension, e.g. ``"fold_accuracy"``.

    Returns:
        The two paths, PNG first.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{name}.{ext}" for ext in ("png", "pdf")]
    for path in paths:
        fig.savefig(path, dpi=150, bbox_inches="tight")
    plt.close(fig)
    return paths


def _label(config: str) -> str:
    return CONFIG_LABELS.get(config, config)


def _offline_folds(folds: pd.DataFrame, config: str) -> pd.DataFrame:
    variant, weighting = config.rsplit("-", 1)
    return folds[(folds.annotations == OFFLINE["annotations"])
                 & (folds.direction == OFFLINE["direction"])
                 & (folds.variant == variant) & (folds.weighting == weighting)]


def per_gesture_accuracy(folds: pd.DataFrame, gestures: Sequence[str], out_dir: Path
                         ) -> list[Path]:
    """Grouped bars, one per compared model: each gesture's accuracy (percent), mean and std over
    the folds where it occurs.

    Args:
        folds: one row per configuration and fold (``collect.per_fold``), with the columns
            ``gesture_accuracy_<gesture>``.
        gestures: the gesture class names, in class order.
        out_dir: the folder written into.

    Returns:
        The PNG and PDF written; empty when the grid ran none of the compared models, or no
        gestures are given.
    """
    rows = {c: r for c in COMPARED if not (r := _offline_folds(folds, c)).empty}
    if not rows or not gestures:
        return []
    fig, ax = plt.subplots(figsize=(8, 3.2))
    width = 0.8 / len(rows)
    x = np.arange(len(gestures))
    for k, (config, table) in enumerate(rows.items()):
        values = table.reindex(columns=[f"gesture_accuracy_{g}" for g in gestures])
        mean, std = values.mean(), values.std(ddof=1).fillna(0.0)
        at = x + (k - (len(rows) - 1) / 2) * width
        ax.bar(at, mean.fillna(0.0), width, yerr=std, capsize=2, label=_label(config),
               error_kw={"elinewidth": 0.8})
        for position, value in zip(at, mean):
            if np.isnan(value) or value == 0:       # absent everywhere / never recognised
                ax.text(position, 1.5, "n/a" if np.isnan(value) else "0", ha="center",
                        va="bottom", fontsize=6, rotation=90, color="0.35")
    ax.set_xticks(x, gestures)
    ax.set_ylabel("accuracy [%]")
    ax.set_ylim(0, 105)
    ax.set_title("Recognition accuracy of individual gestures: mean and std over the folds where "
                 "each occurs (0: never recognised, n/a: in no test set)", fontsize=8)
    ax.legend(fontsize=7, ncol=len(rows), loc="upper center", bbox_to_anchor=(0.5, -0.1))
    return save(fig, out_dir, "per_gesture_accuracy")


def _run_dir(grid_dir: Path, config: str, fold: str) -> Path:
    variant, weighting = config.rsplit("-", 1)
    return grid_dir / RunKey(OFFLINE["annotations"], OFFLINE["direction"], variant, weighting, 0,
                             fold).path()


def _predictions(grid_dir: Path, config: str, fold: str) -> dict[str, Path]:
    """The last evaluation point's per-trial prediction files of one run (seed 0)."""
    return kept_predictions(_run_dir(grid_dir, config, fold))


def _trial_predictions(grid_dir: Path, configs: Sequence[str], trial: str, fold: str
                       ) -> dict[str, pd.DataFrame]:
    """The predictions of ``trial`` (one row per 5 Hz sample) by each of ``configs`` whose run on
    ``fold`` predicted it, by configuration."""
    return {c: pd.read_csv(files[trial]) for c in configs
            if trial in (files := _predictions(grid_dir, c, fold))}


def trial_folds(grid_dir: Path, folds: Sequence[str], config: str = SEGMENTATION_RUNS[0]
                ) -> dict[str, str]:
    """Every test trial of ``config``'s seed-0 runs (offline), in order: trial -> fold.

    Args:
        grid_dir: the grid's folder.
        folds: the folds (test users) to look in, e.g. ``["B", "C"]``.
        config: ``<variant>-<weighting>`` whose runs are read.
    """
    return {trial: fold for fold in folds for trial in _predictions(grid_dir, config, fold)}


def class_names(predictions: pd.DataFrame, task: str) -> tuple[str, ...]:
    """A task's classes, in index order, from the score columns ``<task>_p_<class>`` of its
    predictions; ``()`` for a task without them (regression, ordinal outputs)."""
    prefix = f"{task}_p_"
    return tuple(c.removeprefix(prefix) for c in predictions.columns if c.startswith(prefix))


def accuracy_classes(folds: pd.DataFrame, task: str = "gesture") -> tuple[str, ...]:
    """A task's classes, in class order, from the per-class accuracy columns
    ``<task>_accuracy_<class>`` of ``folds`` (``collect.per_fold``)."""
    prefix = f"{task}_accuracy_"
    return tuple(c.removeprefix(prefix) for c in folds.columns
                 if c.startswith(prefix) and c != f"{prefix}pooled")


def _indices(labels: pd.Series, names: Sequence[str]) -> np.ndarray:
    """``[T]`` class indices of a predictions column of class names (``rnn_seg.predictions``)."""
    return pd.Categorical(labels, categories=list(names)).codes.astype(np.int64)


def _seconds(predictions: pd.DataFrame) -> np.ndarray:
    """Time of each sample from the 30 Hz frame (1-based) it came from."""
    return (predictions.frame.to_numpy() - 1) / KINEMATICS_HZ


def segmentation_example(grid_dir: Path, trial: str, fold: str, out_dir: Path) -> list[Path]:
    """Ribbons of ground truth, A and APoc for one test trial, over time in seconds.

    Args:
        grid_dir: the grid's folder.
        trial: the trial's name, e.g. ``"Suturing_B001"``.
        fold: the fold (test user) whose runs predicted it.
        out_dir: the folder written into.

    Returns:
        The PNG and PDF written; empty when no run predicted the trial.
    """
    runs = _trial_predictions(grid_dir, SEGMENTATION_RUNS, trial, fold)
    if not runs:
        return []
    first = next(iter(runs.values()))
    names = class_names(first, "gesture")
    colours = task_colours(len(names), ordered=False)
    times = _seconds(first)
    ribbons = [Ribbon("ground truth", _indices(first.gesture_true, names), times, names, colours)]
    ribbons += [Ribbon(_label(c), _indices(p.gesture, names), times, names, colours)
                for c, p in runs.items()]
    fig, axes = plt.subplots(len(ribbons), 1, figsize=(10, 2.2), sharex=True)
    for ax, ribbon in zip(axes, ribbons):
        draw_ribbon(ax, ribbon)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title(f"{trial}: gesture segmentation", fontsize=9)
    layout_with_legends(fig, ribbons)
    return save(fig, out_dir, "segmentation_example")


def progress_example(grid_dir: Path, trial: str, fold: str, out_dir: Path) -> list[Path]:
    """True progress of one test trial and the predictions over time in seconds: APr's raw
    regression output (a line), APc's and APoc's stages (steps). Arguments and return value as
    ``segmentation_example``'s.
    """
    runs = _trial_predictions(grid_dir, PROGRESS_RUNS, trial, fold)
    if not runs:
        return []
    fig, ax = plt.subplots(figsize=(9, 2.8))
    first = next(iter(runs.values()))
    times = _seconds(first)
    names = load_task(grid_task_name(grid_dir)).stage_names
    ax.step(times, _indices(first.progress_true, names), where="post", color="k", lw=2,
            label="truth")
    for config, predictions in runs.items():
        if "progress_value" in predictions:
            ax.plot(times, predictions.progress_value, color="tab:red", lw=1,
                    label=f"{_label(config)}: regression output")
        else:
            ax.step(times, _indices(predictions.progress, names), where="post", alpha=0.8,
                    label=_label(config))
    ax.set_yticks(range(len(names)), names)
    ax.set_ylabel("progress stage")
    ax.set_xlabel("time [s]")
    ax.set_xlim(times[0], times[-1])
    ax.set_title(f"{trial}: progress prediction", fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1))
    return save(fig, out_dir, "progress_example")


def fold_accuracy(folds: pd.DataFrame, out_dir: Path) -> list[Path]:
    """Gesture vs progress accuracy, one point per fold labelled with its test user: APoc's (the
    paper's Fig. 7), or every two-task configuration's if the grid ran no APoc."""
    if not {"gesture_accuracy", "progress_accuracy"} <= set(folds):
        return []
    both = folds.dropna(subset=["gesture_accuracy", "progress_accuracy"])
    configs = [c for c in FOLD_RUNS if not _offline_folds(both, c).empty] or list(dict.fromkeys(
        f"{r.variant}-{r.weighting}" for r in both.itertuples()))
    tables = {c: t for c in configs if not (t := _offline_folds(both, c)).empty}
    if not tables:
        return []
    fig, ax = plt.subplots(figsize=(4.5, 4))
    for config, table in tables.items():
        points = ax.scatter(table.gesture_accuracy, table.progress_accuracy, s=22,
                            label=_label(config))
        for row in table.itertuples():
            ax.annotate(row.fold, (row.gesture_accuracy, row.progress_accuracy), fontsize=9,
                        xytext=(4, 3), textcoords="offset points",
                        color=points.get_facecolor()[0])
    ax.set_xlabel("gesture accuracy [%]")
    ax.set_ylabel("progress accuracy [%]")
    ax.set_title("Per fold (test user): gesture vs progress accuracy", fontsize=9)
    ax.legend(fontsize=7)
    return save(fig, out_dir, "fold_accuracy")


def gradnorm_weights(grid_dir: Path, out_dir: Path) -> list[Path]:
    """Task weights of every GradNorm run (thin lines per fold), one panel per variant."""
    logs = sorted((grid_dir / "runs" / OFFLINE["annotations"] / OFFLINE["direction"])
                  .glob("*-gradnorm/seed0/*/gradnorm.csv"))
    by_variant: dict[str, list[pd.DataFrame]] = {}
    for log in logs:
        by_variant.setdefault(log.parts[-4].removesuffix("-gradnorm"), []).append(pd.read_csv(log))
    if not by_variant:
        return []
    fig, axes = plt.subplots(1, len(by_variant), figsize=(3.3 * len(by_variant), 2.8),
                             squeeze=False, sharey=True)
    for ax, (variant, frames) in zip(axes[0], sorted(by_variant.items())):
        for frame in frames:
            for column, color in (("w_end_gesture", "tab:blue"), ("w_end_progress", "tab:red")):
                ax.plot(frame.unit, frame[column], color=color, alpha=0.35, lw=1)
        ax.plot([], [], color="tab:blue", label="w gesture")
        ax.plot([], [], color="tab:red", label="w progress")
        ax.set_title(f"{variant} (alpha 1.5)", fontsize=9)
        ax.set_xlabel("epoch")
    axes[0][0].set_ylabel("task weight")
    axes[0][0].legend(fontsize=7)
    return save(fig, out_dir, "gradnorm_weights")


def example_trial(grid_dir: Path, folds: pd.DataFrame, requested: str | None = None
                  ) -> tuple[str, str] | None:
    """``(trial, fold)`` of the example figures; None if the grid has no run to show.

    Args:
        grid_dir: the grid's folder.
        folds: one row per configuration and fold (``collect.per_fold``).
        requested: a test trial's name (e.g. ``Suturing_B001``); None = the first test trial of
            the first fold. One that no run tested raises ``ValueError`` listing the choices.
    """
    trials = trial_folds(grid_dir, sorted(folds.fold.unique()))
    if requested is None:
        return next(iter(trials.items()), None)
    if not trials:
        raise ValueError(f"example trial {requested!r}: no seed-0 {SEGMENTATION_RUNS[0]} run of "
                         "the grid kept its predictions (a scores archive keeps none); leave out "
                         "--example-trial")
    if requested not in trials:
        raise ValueError(f"example trial {requested!r} is not a test trial of the grid's "
                         f"{SEGMENTATION_RUNS[0]} runs; choose one of {', '.join(trials)}")
    return requested, trials[requested]


def all_figures(grid_dir: Path, folds: pd.DataFrame, out_dir: Path,
                example: tuple[str, str] | None, gradnorm: bool = True) -> list[Path]:
    """Every figure the grid has the runs for.

    Args:
        grid_dir: the grid's folder.
        folds: one row per configuration and fold (``collect.per_fold``).
        out_dir: the folder written into.
        example: ``(trial, fold)`` of the example figures (``example_trial``); None = no
            example figures. A figure not drawn (its runs are missing) is removed from
            ``out_dir`` if an earlier call left one there.
        gradnorm: also draw the GradNorm weights (read from every GradNorm run's folder).

    Returns:
        Every PNG and PDF written.
    """
    written = per_gesture_accuracy(folds, accuracy_classes(folds), out_dir)
    if example is not None:
        trial, fold = example
        written += segmentation_example(grid_dir, trial, fold, out_dir)
        written += progress_example(grid_dir, trial, fold, out_dir)
    written += fold_accuracy(folds, out_dir)
    written += gradnorm_weights(grid_dir, out_dir) if gradnorm else []
    _remove_stale(out_dir, set(FIGURES) - {path.stem for path in written})
    return written


def _remove_stale(out_dir: Path, names: set[str]) -> None:
    """Remove ``names``' PNG and PDF from ``out_dir``: figures an earlier grid drew there that
    this one cannot, which would otherwise pass for this grid's."""
    for name in sorted(names):
        for ext in ("png", "pdf"):
            (out_dir / f"{name}.{ext}").unlink(missing_ok=True)
