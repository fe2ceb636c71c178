"""The paper's figures from a grid's runs, each saved as PNG and PDF.

* ``per_gesture_accuracy``: accuracy of each gesture, A vs APoc (paper Fig. 4);
* ``segmentation_example``: ground truth, A and APoc ribbons for one test trial (Fig. 5);
* ``progress_example``: predicted vs true progress stage over time (Fig. 6);
* ``fold_accuracy``: gesture vs progress accuracy per fold (Fig. 7);
* ``gradnorm_weights``: task weights over training for the GradNorm runs.

Figures read the revised-annotation, bidirectional runs of seed 0 where one run is needed. The
gesture classes and progress stages are the grid's task's, read from the runs' own metric columns
(``gesture_accuracy_<gesture>``, ``progress_accuracy_P<k>``), so any task's grid draws correctly.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from jigsaws_tools.plots import draw_ribbon, legend_handles  # noqa: E402

from .collect import lookup  # noqa: E402
from .grid_spec import RunKey  # noqa: E402
from .tables import CONFIG_LABELS  # noqa: E402

OFFLINE = {"annotations": "revised", "direction": "bidirectional"}
COMPARED = ("A-fixed", "APoc-fixed", "APoc-gradnorm")


def save(fig: plt.Figure, out_dir: Path, name: str) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{name}.{ext}" for ext in ("png", "pdf")]
    fig.tight_layout()
    for path in paths:
        fig.savefig(path, dpi=150, bbox_inches="tight")
    plt.close(fig)
    return paths


def _label(config: str) -> str:
    return CONFIG_LABELS.get(config, config)


def _offline(summary: pd.DataFrame, config: str) -> pd.Series | None:
    return lookup(summary, OFFLINE["annotations"], OFFLINE["direction"], config)


def class_names(table: pd.DataFrame, task: str) -> list[str]:
    """The classes of ``task`` (``"gesture"`` or ``"progress"``) in the order of the runs' metric
    columns ``<task>_accuracy_<class>[_mean]`` of ``table`` (a summary or per-fold table)."""
    prefix = f"{task}_accuracy_"
    names = [c.removeprefix(prefix).removesuffix("_mean") for c in table.columns
             if c.startswith(prefix) and not c.endswith("_std")]
    return list(dict.fromkeys(names))


def per_gesture_accuracy(summary: pd.DataFrame, out_dir: Path) -> list[Path]:
    """Grouped bars: mean over folds of each gesture's accuracy, one bar per compared model."""
    rows = {c: r for c in COMPARED if (r := _offline(summary, c)) is not None}
    gestures = class_names(summary, "gesture")
    if not rows or not gestures:
        return []
    fig, ax = plt.subplots(figsize=(8, 3.2))
    width = 0.8 / len(rows)
    x = np.arange(len(gestures))
    for k, (config, row) in enumerate(rows.items()):
        values = [row.get(f"gesture_accuracy_{g}_mean", np.nan) for g in gestures]
        ax.bar(x + (k - (len(rows) - 1) / 2) * width, values, width, label=_label(config))
    ax.set_xticks(x, gestures)
    ax.set_ylabel("accuracy [%]")
    ax.set_ylim(0, 100)
    ax.set_title("Recognition accuracy of individual gestures (mean over folds)", fontsize=9)
    ax.legend(fontsize=7, ncol=len(rows), loc="upper center", bbox_to_anchor=(0.5, -0.1))
    return save(fig, out_dir, "per_gesture_accuracy")


def _predictions(grid_dir: Path, config: str, fold: str) -> dict[str, pd.DataFrame]:
    """The last evaluation point's per-trial predictions of one run (seed 0): name -> frame."""
    variant, weighting = config.rsplit("-", 1)
    run = grid_dir / RunKey(OFFLINE["annotations"], OFFLINE["direction"], variant, weighting, 0,
                            fold).path()
    points = sorted((run / "eval").glob("*/predictions"))
    if not points:
        return {}
    return {p.stem: pd.read_csv(p) for p in sorted(points[-1].glob("*.csv"))}


def segmentation_example(grid_dir: Path, fold: str, gestures: list[str], out_dir: Path
                         ) -> list[Path]:
    """Ribbons of ground truth, A and APoc for the first test trial of ``fold`` in both runs.

    Args:
        grid_dir: the grid's output folder.
        fold: the test user whose trial is shown.
        gestures: the task's gesture classes, in class order.
        out_dir: where the figure goes.
    """
    runs = {c: _predictions(grid_dir, c, fold) for c in ("A-fixed", "APoc-fixed")}
    common = sorted(set.intersection(*(set(r) for r in runs.values())))
    if not common:
        return []
    trial = common[0]
    first = runs["A-fixed"][trial]
    rows = [("ground truth", first.gesture_true.to_numpy())]
    rows += [(_label(c), r[trial].gesture_pred.to_numpy()) for c, r in runs.items()]
    fig, axes = plt.subplots(len(rows), 1, figsize=(10, 2.2), sharex=True)
    for ax, (name, labels) in zip(axes, rows):
        draw_ribbon(ax, labels, len(gestures), "tab10", name)
    _time_axis(axes[-1], first.frame.to_numpy())
    axes[0].set_title(f"{trial}: gesture segmentation", fontsize=9)
    fig.legend(handles=legend_handles(gestures, "tab10"), loc="lower center", ncol=10, fontsize=6,
               bbox_to_anchor=(0.5, -0.08))
    return save(fig, out_dir, "segmentation_example")


def progress_example(grid_dir: Path, fold: str, num_stages: int, out_dir: Path) -> list[Path]:
    """True and predicted progress stage (``0..num_stages-1``) over time, APc and APoc, first
    common test trial."""
    runs = {c: r for c in ("APc-fixed", "APoc-fixed") if (r := _predictions(grid_dir, c, fold))}
    if not runs:
        return []
    trial = sorted(set.intersection(*(set(r) for r in runs.values())))[0]
    fig, ax = plt.subplots(figsize=(9, 2.8))
    first = next(iter(runs.values()))[trial]
    seconds = first.frame.to_numpy() / 30.0
    ax.step(seconds, first.progress_true, where="post", color="k", lw=2, label="truth")
    for config, preds in runs.items():
        ax.step(seconds, preds[trial].progress_pred, where="post", alpha=0.8, label=_label(config))
    ax.set_yticks(range(num_stages))
    ax.set_ylabel("progress stage")
    ax.set_xlabel("time [s]")
    ax.set_title(f"{trial}: progress prediction", fontsize=9)
    ax.legend(fontsize=7)
    return save(fig, out_dir, "progress_example")


def _time_axis(ax: plt.Axes, frames: np.ndarray) -> None:
    ticks = np.linspace(0, len(frames) - 1, 6).astype(int)
    ax.set_xticks(ticks, [f"{frames[t] / 30:.0f}" for t in ticks])
    ax.set_xlabel("time [s]")


def fold_accuracy(folds: pd.DataFrame, out_dir: Path) -> list[Path]:
    """Scatter of gesture vs progress accuracy, one point per fold, per multi-task model."""
    offline = folds[(folds.annotations == OFFLINE["annotations"])
                    & (folds.direction == OFFLINE["direction"])]
    if "progress_accuracy" not in offline or "gesture_accuracy" not in offline:
        return []
    both = offline.dropna(subset=["gesture_accuracy", "progress_accuracy"])
    if both.empty:
        return []
    fig, ax = plt.subplots(figsize=(4.5, 4))
    for (variant, weighting), group in both.groupby(["variant", "weighting"]):
        ax.scatter(group.gesture_accuracy, group.progress_accuracy, s=18,
                   label=_label(f"{variant}-{weighting}"))
        for row in group.itertuples():
            ax.annotate(row.fold, (row.gesture_accuracy, row.progress_accuracy), fontsize=6)
    ax.set_xlabel("gesture accuracy [%]")
    ax.set_ylabel("progress accuracy [%]")
    ax.set_title("Per fold: gesture vs progress accuracy", fontsize=9)
    ax.legend(fontsize=6)
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


def all_figures(grid_dir: Path, summary: pd.DataFrame, folds: pd.DataFrame, out_dir: Path
                ) -> list[Path]:
    """Every figure the grid has the runs for; the example trial is from the first fold."""
    first_fold = sorted(folds.fold.unique())[0]
    return [*per_gesture_accuracy(summary, out_dir),
            *segmentation_example(grid_dir, first_fold, class_names(summary, "gesture"), out_dir),
            *progress_example(grid_dir, first_fold, len(class_names(summary, "progress")),
                              out_dir),
            *fold_accuracy(folds, out_dir),
            *gradnorm_weights(grid_dir, out_dir)]
