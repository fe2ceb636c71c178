"""The paper's figures from a grid's runs, each saved as PNG and PDF.

* ``per_gesture_accuracy``: accuracy of each gesture, A vs APoc (paper Fig. 4): the mean over the
  folds whose test trials contain the gesture, one standard deviation each side (clipped to
  [0, 100]) as error bar, and under a gesture missing from some folds the number it occurs in; a
  gesture that occurs but is never recognised shows as 0, one absent from every test set as n/a;
* ``segmentation_example``: ground truth, A and APoc ribbons of one test trial (Fig. 5);
* ``progress_example``: true progress (a grey band) and APr's regression output, APc's and APoc's
  predicted stages over time, stages named from the task file (Fig. 6);
* ``fold_accuracy``: per fold, the gesture accuracy of A beside APoc;
* ``gesture_vs_progress``: gesture against progress accuracy of APoc, a point per fold (Fig. 7;
  without APoc runs, the first two-task configuration);
* ``gradnorm_weights``: task weights over training for the GradNorm runs, in the paper's order of
  the variants, on a common epoch axis.

Figures read the revised-annotation, bidirectional runs of seed 0 where one run is needed; the
example trial is a choice (``--example-trial``); the two example figures draw that trial's
predictions as a run's folder or its scores archive keeps them (``multitask.grid.kept_predictions``:
the same arrays from either) beside its true labels and times, re-read from the data
(``ExampleTrial``). Time is in seconds; class names come from the per-class accuracy columns of
the runs' metrics (``gesture_accuracy_<class>``) and from the kept predictions (the run's task),
colours from ``jigsaws_tools.plots``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from jigsaws_tools.plots import (COLUMN_INCHES, LEGEND_ROW_INCHES, PAGE_INCHES,  # noqa: E402
                                 Ribbon, draw_ribbon, figure_style, layout_with_legends,
                                 legend_rows, task_colours)

from rnn_seg.runs.folder import read_json  # noqa: E402
from rnn_seg.runs.logs import read_log  # noqa: E402

from ...grid.kept_predictions import (KeptPredictions, TrialTruth, kept_trials,  # noqa: E402
                                      read_kept_predictions, read_truth)
from ...grid.spec import RunKey  # noqa: E402
from ..statistics.paired import ConfigId  # noqa: E402
from . import drawing  # noqa: E402
from .tables import CONFIG_LABELS  # noqa: E402

OFFLINE = {"annotations": "revised", "direction": "bidirectional"}
COMPARED = ("A-fixed", "APoc-fixed", "APoc-gradnorm")
#: Runs shown by the example figures: segmentation, then progress (regression output first).
SEGMENTATION_RUNS = ("A-fixed", "APoc-fixed")
PROGRESS_RUNS = ("APr-fixed", "APc-fixed", "APoc-fixed")
#: The multi-task model of the gesture-vs-progress figure, first the grid ran (paper's Fig. 7).
FOLD_RUNS = ("APoc-gradnorm", "APoc-fixed")
#: GradNorm panels in the paper's order of the variants.
GRADNORM_ORDER = ("APr", "APc", "APoc")
#: Legend name -> (gradnorm.csv column, colour) of the task-weight lines.
WEIGHT_LINES = {"gesture weight $w_1$": ("w_end_gesture", "tab:blue"),
                "progress weight $w_2$": ("w_end_progress", "tab:red")}


@figure_style
def save(fig: plt.Figure, out_dir: Path, name: str) -> list[Path]:
    """Write ``fig`` as ``<name>.png`` (150 dpi) and ``<name>.pdf`` and close it; the PDF without
    its creation date, so that the same evidence draws the same bytes, and with TrueType fonts
    (``jigsaws_tools.plots.FIGURE_STYLE``).

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
        fig.savefig(path, dpi=150, bbox_inches="tight", pad_inches=0.02,
                    metadata={"CreationDate": None} if path.suffix == ".pdf" else None)
    plt.close(fig)
    drawing.drew(name)
    return paths


#: Parenthesised detail of a model label (``tables.CONFIG_LABELS``) -> its mathtext in figures.
_MATH_DETAILS = {"w1=w2=1": "$w_1 = w_2 = 1$", "alpha=1.5": r"GradNorm, $\alpha = 1.5$"}


def label(config: str) -> str:
    """A configuration's name in figures, e.g. ``APoc (GradNorm, $\alpha = 1.5$)``."""
    text = CONFIG_LABELS.get(config, config)
    for plain, math in _MATH_DETAILS.items():
        text = text.replace(plain, math)
    return text


@figure_style
def per_gesture_accuracy(folds: pd.DataFrame, gestures: Sequence[str], out_dir: Path
                         ) -> list[Path]:
    """Grouped bars, one per compared model: each gesture's accuracy (percent), mean over the
    folds where it occurs, with one standard deviation each side clipped to [0, 100]; a gesture
    missing from some folds' test trials says in how many it occurs.

    Args:
        folds: one row per configuration and fold (``collect.per_fold``), with the columns
            ``gesture_accuracy_<gesture>``.
        gestures: the gesture class names, in class order.
        out_dir: the folder written into.

    Returns:
        The PNG and PDF written; empty when the grid ran none of the compared models, or no
        gestures are given.
    """
    rows = {c: r for c in COMPARED if not (r := ConfigId.parse(c).select(folds)).empty}
    if not rows or not gestures:
        return []
    fig, ax = plt.subplots(figsize=(PAGE_INCHES, 2.8))
    width = 0.8 / len(rows)
    x = np.arange(len(gestures))
    for k, (config, table) in enumerate(rows.items()):
        values = table.reindex(columns=[f"gesture_accuracy_{g}" for g in gestures])
        mean, std = values.mean().to_numpy(), values.std(ddof=1).fillna(0.0).to_numpy()
        below = np.nan_to_num(mean - np.clip(mean - std, 0, 100))
        above = np.nan_to_num(np.clip(mean + std, 0, 100) - mean)
        at = x + (k - (len(rows) - 1) / 2) * width
        ax.bar(at, np.nan_to_num(mean), width, yerr=[below, above], capsize=2,
               label=label(config), error_kw={"elinewidth": 0.8})
        for position, value in zip(at, mean):
            if np.isnan(value) or value == 0:       # absent everywhere / never recognised
                ax.text(position, 1.5, "n/a" if np.isnan(value) else "0", ha="center",
                        va="bottom", rotation=90, color="0.35")
    occurs = next(iter(rows.values())).reindex(
        columns=[f"gesture_accuracy_{g}" for g in gestures]).notna().sum().to_numpy()
    total = len(next(iter(rows.values())))
    ax.set_xticks(x, [g if n == total else f"{g}\n{n} of {total}\nfolds"
                      for g, n in zip(gestures, occurs)])
    ax.set_ylabel("accuracy [%]")
    ax.set_ylim(0, 103)                          # room for the caps of bars reaching 100
    ax.set_yticks(range(0, 101, 20))
    ax.legend(ncol=len(rows), loc="lower center", bbox_to_anchor=(0.5, 1.0), frameon=False)
    return save(fig, out_dir, "per_gesture_accuracy")


def _run_dir(grid_dir: Path, config: str, fold: str) -> Path:
    variant, weighting = config.rsplit("-", 1)
    return grid_dir / RunKey(OFFLINE["annotations"], OFFLINE["direction"], variant, weighting, 0,
                             fold).path()


@dataclass(frozen=True)
class ExampleTrial:
    """The test trial of the example figures: its name (e.g. ``Suturing_D003``), its fold (test
    user) and, re-read from the data, its samples' frames and true labels."""

    name: str
    fold: str
    truth: TrialTruth


def _trial_predictions(grid_dir: Path, configs: Sequence[str], example: ExampleTrial
                       ) -> dict[str, KeptPredictions]:
    """The kept predictions of the seed-0 runs of ``configs`` on the example's fold that
    predicted its trial, by configuration."""
    runs = {c: read_kept_predictions(_run_dir(grid_dir, c, example.fold)) for c in configs}
    return {c: kept for c, kept in runs.items() if kept and example.name in kept.trials}


def trial_folds(grid_dir: Path, folds: Sequence[str], config: str = SEGMENTATION_RUNS[0]
                ) -> dict[str, str]:
    """Every test trial of ``config``'s seed-0 runs (offline), in order: trial -> fold.

    Args:
        grid_dir: the grid's folder.
        folds: the folds (test users) to look in, e.g. ``["B", "C"]``.
        config: ``<variant>-<weighting>`` whose runs are read.
    """
    return {trial: fold for fold in folds
            for trial in kept_trials(_run_dir(grid_dir, config, fold))}


def example_truth(grid_dir: Path, trial: str, fold: str, data_dir: Path | None = None
                  ) -> ExampleTrial:
    """The example trial ``trial`` of ``fold`` with its frames and true labels, from the data
    the seed-0 ``SEGMENTATION_RUNS[0]`` run trained on (``data_dir``, else the folder its
    config.json records; ``multitask.grid.kept_predictions.read_truth``).

    Raises:
        OSError: that data is not here; ValueError: it holds no such trial, or one of another
            length than the run's predictions of it (other data than the run's).
    """
    run_dir = _run_dir(grid_dir, SEGMENTATION_RUNS[0], fold)
    truth = read_truth(run_dir, trial, data_dir)
    kept = read_kept_predictions(run_dir)
    predicted = len(next(iter(kept.trials[trial].labels.values())))
    if predicted != len(truth.frames):
        raise ValueError(f"its {trial} has {len(truth.frames)} samples, the run {run_dir} "
                         f"predicted {predicted}: not the data the run trained on")
    return ExampleTrial(trial, fold, truth)


def accuracy_classes(folds: pd.DataFrame, task: str = "gesture") -> tuple[str, ...]:
    """A task's classes, in class order, from the per-class accuracy columns
    ``<task>_accuracy_<class>`` of ``folds`` (``collect.per_fold``)."""
    prefix = f"{task}_accuracy_"
    return tuple(c.removeprefix(prefix) for c in folds.columns
                 if c.startswith(prefix) and c != f"{prefix}pooled")


@figure_style
def segmentation_example(grid_dir: Path, example: ExampleTrial, out_dir: Path) -> list[Path]:
    """Ribbons of ground truth, A and APoc for one test trial, over time in seconds.

    Args:
        grid_dir: the grid's folder (or its scores archive).
        example: the trial, its fold and its true labels (``example_truth``).
        out_dir: the folder written into.

    Returns:
        The PNG and PDF written; empty when no run predicted the trial.
    """
    runs = _trial_predictions(grid_dir, SEGMENTATION_RUNS, example)
    if not runs:
        return []
    names = next(iter(runs.values())).classes["gesture"]
    colours = task_colours(len(names), ordered=False)
    times = example.truth.seconds
    ribbons = [Ribbon("ground truth", example.truth.labels["gesture"], times, names, colours)]
    ribbons += [Ribbon(label(c), kept.trials[example.name].labels["gesture"], times, names,
                       colours) for c, kept in runs.items()]
    fig, axes = plt.subplots(len(ribbons), 1, sharex=True, figsize=(
        PAGE_INCHES, 0.45 * len(ribbons) + 0.6 + LEGEND_ROW_INCHES * legend_rows(ribbons)))
    for ax, ribbon in zip(axes, ribbons):
        draw_ribbon(ax, ribbon)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title(f"{example.name}: gesture segmentation")
    layout_with_legends(fig, ribbons)
    return save(fig, out_dir, "segmentation_example")


@figure_style
def progress_example(grid_dir: Path, example: ExampleTrial, out_dir: Path) -> list[Path]:
    """True progress of one test trial (a wide grey band, so that it shows beneath the
    predictions) and the predictions over time in seconds: APr's raw regression output (a line),
    APc's and APoc's stages (steps); stages named from the runs' task. Arguments and return
    value as ``segmentation_example``'s.
    """
    runs = _trial_predictions(grid_dir, PROGRESS_RUNS, example)
    if not runs:
        return []
    fig, ax = plt.subplots(figsize=(PAGE_INCHES, 2.8))
    times = example.truth.seconds
    names = next(iter(runs.values())).classes["progress"]
    ax.step(times, example.truth.labels["progress"], where="post", color="0.55", lw=6,
            alpha=0.5, solid_capstyle="butt", label="ground truth", zorder=1)
    for config, kept in runs.items():
        predictions = kept.trials[example.name]
        if "progress" in predictions.values:
            ax.plot(times, predictions.values["progress"], color="tab:red", lw=1, zorder=3,
                    label=f"{label(config)}: regression output")
        else:
            ax.step(times, predictions.labels["progress"], where="post", lw=1.2,
                    zorder=2, label=label(config))
    ax.set_yticks(range(len(names)), names)
    ax.set_ylabel("progress stage")
    ax.set_xlabel("time [s]")
    ax.set_xlim(times[0], times[-1])
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, frameon=False,
              title=f"{example.name}: progress prediction")  # above the axes, clear of the lines
    return save(fig, out_dir, "progress_example")


@figure_style
def fold_accuracy(folds: pd.DataFrame, out_dir: Path) -> list[Path]:
    """Per fold (test user), the gesture accuracy of each compared model, A beside APoc: where
    the folds differ, and whether the models move together across them."""
    compared = {c: t for c in COMPARED if not (t := ConfigId.parse(c).select(folds)).empty}
    if not compared or "gesture_accuracy" not in folds:
        return []
    fig, ax = plt.subplots(figsize=(COLUMN_INCHES, 2.9))
    letters = sorted(set().union(*(t.fold for t in compared.values())))
    width = 0.8 / len(compared)
    for k, (config, table) in enumerate(compared.items()):
        at = [letters.index(f) + (k - (len(compared) - 1) / 2) * width for f in table.fold]
        ax.plot(at, table.gesture_accuracy, "o", ms=5, label=label(config))
    ax.set_xticks(range(len(letters)), letters)
    ax.set_xlabel("fold (test user)")
    ax.set_ylabel("gesture accuracy [%]")
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), frameon=False,
              handletextpad=0.1)
    fig.tight_layout()
    return save(fig, out_dir, "fold_accuracy")


@figure_style
def gesture_vs_progress(folds: pd.DataFrame, out_dir: Path) -> list[Path]:
    """The paper's Fig. 7: gesture against progress accuracy of one multi-task model, a point
    per fold labelled with its test user (APoc with GradNorm, else APoc with fixed weights, else
    the first two-task configuration)."""
    if not {"gesture_accuracy", "progress_accuracy"} <= set(folds):
        return []
    both = folds.dropna(subset=["gesture_accuracy", "progress_accuracy"])
    two_task = [c for c in FOLD_RUNS if not ConfigId.parse(c).select(both).empty] or list(
        dict.fromkeys(f"{r.variant}-{r.weighting}" for r in both.itertuples()))
    if not two_task:
        return []
    points = ConfigId.parse(two_task[0]).select(both)
    fig, ax = plt.subplots(figsize=(COLUMN_INCHES, 2.9))
    ax.scatter(points.gesture_accuracy, points.progress_accuracy, s=MARKER_PT ** 2,
               color="tab:green")
    ax.set_xlabel("gesture accuracy [%]")
    ax.set_ylabel("progress accuracy [%]")
    ax.set_title(label(two_task[0]))
    ax.set_xlim(*_padded(points.gesture_accuracy.to_numpy()))
    ax.set_ylim(*_padded(points.progress_accuracy.to_numpy()))
    fig.tight_layout()                          # the labels' places are measured in this layout
    _label_points(ax, points.gesture_accuracy.to_numpy(), points.progress_accuracy.to_numpy(),
                  list(points.fold), MARKER_PT)
    return save(fig, out_dir, "gesture_vs_progress")


#: Diameter of the points of ``gesture_vs_progress``, in points.
MARKER_PT = 4.5


def _padded(values: np.ndarray) -> tuple[float, float]:
    """Axis limits around ``values`` with a margin of 10 % of their range plus half a point."""
    margin = 0.1 * np.ptp(values) + 0.5
    return values.min() - margin, values.max() + margin


#: Where a point's label may go, tried in order: offsets from the point in points (1/72 in),
#: with the label's alignment; then the same directions twice and three times as far.
LABEL_PLACES = ((4, 3, "left", "bottom"), (4, -3, "left", "top"), (-4, 3, "right", "bottom"),
                (-4, -3, "right", "top"), (0, 5, "center", "bottom"), (0, -5, "center", "top"),
                (6, 0, "left", "center"), (-6, 0, "right", "center"))
#: Room kept around a marker and between labels, in points.
LABEL_CLEARANCE = 1.5


def _label_points(ax: plt.Axes, x: np.ndarray, y: np.ndarray, texts: Sequence[str],
                  marker_pt: float) -> None:
    """Write ``texts`` beside the points ``(x, y)`` (markers ``marker_pt`` points across), each at
    the first place of ``LABEL_PLACES`` where it overlaps no marker, no label written before it
    and stays inside the axes, farther out with a thin line to its point when no near place is
    free (else where it overlaps least). Call once the axes' limits and the figure's layout are
    final: places are measured as drawn."""
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    to_pixels = fig.dpi / 72
    frame = ax.get_window_extent(renderer)
    centres = ax.transData.transform(np.column_stack([x, y]))
    half = (marker_pt / 2 + LABEL_CLEARANCE) * to_pixels
    taken = [(cx - half, cy - half, cx + half, cy + half) for cx, cy in centres]
    for i in np.argsort(-y):
        text = ax.annotate(texts[i], (x[i], y[i]), textcoords="offset points", xytext=(0, 0))
        best = None
        for reach in (1, 2, 3):
            for dx, dy, ha, va in LABEL_PLACES:
                text.set(position=(dx * reach, dy * reach), ha=ha, va=va)
                box = text.get_window_extent(renderer)
                box = (box.x0, box.y0, box.x1, box.y1)
                clash = sum(_overlap(box, other) for other in taken) + _outside(box, frame)
                if best is None or clash < best[0]:
                    best = (clash, (dx * reach, dy * reach, ha, va, reach), box)
                if clash == 0:
                    break
            if best[0] == 0:
                break
        _, (dx, dy, ha, va, reach), box = best
        text.remove()
        ax.annotate(texts[i], (x[i], y[i]), textcoords="offset points", xytext=(dx, dy), ha=ha,
                    va=va, arrowprops=None if reach == 1 else {
                        "arrowstyle": "-", "lw": 0.5, "color": "0.5", "shrinkA": 0,
                        "shrinkB": marker_pt / 2})
        pad = LABEL_CLEARANCE * to_pixels
        taken.append((box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad))


def _overlap(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Area shared by two boxes ``(x0, y0, x1, y1)``."""
    return (max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
            * max(0.0, min(a[3], b[3]) - max(a[1], b[1])))


def _outside(box: tuple[float, ...], frame) -> float:
    """Area of ``box`` outside the axes' ``frame``, weighted to count as a clash."""
    inside = _overlap(box, (frame.x0, frame.y0, frame.x1, frame.y1))
    return 10 * ((box[2] - box[0]) * (box[3] - box[1]) - inside)


@figure_style
def gradnorm_weights(grid_dir: Path, out_dir: Path) -> list[Path]:
    """Task weights over training of every GradNorm run of seed 0 (a thin line per fold), one
    panel per variant in the paper's order (APr, APc, APoc) on a common epoch axis; each panel
    names its GradNorm alpha (from the runs' config.json, where it records one)."""
    root = grid_dir / "runs" / OFFLINE["annotations"] / OFFLINE["direction"]
    panels = {v: sorted(root.glob(f"{v}-gradnorm/seed0/*/gradnorm.csv")) for v in GRADNORM_ORDER}
    panels = {v: logs for v, logs in panels.items() if logs}
    if not panels:
        return []
    fig, axes = plt.subplots(1, len(panels), figsize=(PAGE_INCHES, 2.5), squeeze=False,
                             sharex=True, sharey=True)
    for ax, (variant, logs) in zip(axes[0], panels.items()):
        for log in logs:
            frame = read_log(log)
            for column, colour in WEIGHT_LINES.values():
                ax.plot(frame.unit, frame[column], color=colour, alpha=0.35, lw=1)
        alpha = read_json(logs[0].parent / "config.json").get("gradnorm", {}).get("alpha")
        detail = "" if alpha is None else rf", $\alpha = {alpha:g}$"
        ax.set_title(f"{variant} (GradNorm{detail})")
        ax.set_xlabel("epoch")
    axes[0][0].set_ylabel("task weight")
    handles = [plt.Line2D([], [], color=colour, label=name)
               for name, (_, colour) in WEIGHT_LINES.items()]
    fig.tight_layout()
    fig.legend(handles=handles, ncol=len(handles), loc="lower center",
               bbox_to_anchor=(0.5, 1.0), frameon=False,
               title="one line per fold")       # above the panels, clear of every line
    return save(fig, out_dir, "gradnorm_weights")


def example_trial(grid_dir: Path, folds: pd.DataFrame, requested: str | None = None
                  ) -> tuple[str, str] | None:
    """``(trial, fold)`` of the example figures (``example_truth`` adds its true labels); None
    if the grid has no run to show.

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
                         "the grid kept its predictions (an archive written before predictions "
                         "were kept has none); leave out --example-trial")
    if requested not in trials:
        raise ValueError(f"example trial {requested!r} is not a test trial of the grid's "
                         f"{SEGMENTATION_RUNS[0]} runs; choose one of {', '.join(trials)}")
    return requested, trials[requested]


def all_figures(grid_dir: Path, folds: pd.DataFrame, out_dir: Path,
                example: ExampleTrial | None, gradnorm: bool = True) -> list[Path]:
    """Every figure the grid has the runs for.

    Args:
        grid_dir: the grid's folder.
        folds: one row per configuration and fold (``collect.per_fold``).
        out_dir: the folder written into.
        example: the trial of the example figures (``example_truth``); None = no example
            figures.
        gradnorm: also draw the GradNorm weights (read from every GradNorm run's folder).

    Returns:
        Every PNG and PDF written.
    """
    written = per_gesture_accuracy(folds, accuracy_classes(folds), out_dir)
    if example is not None:
        written += segmentation_example(grid_dir, example, out_dir)
        written += progress_example(grid_dir, example, out_dir)
    written += fold_accuracy(folds, out_dir)
    written += gesture_vs_progress(folds, out_dir)
    written += gradnorm_weights(grid_dir, out_dir) if gradnorm else []
    return written
