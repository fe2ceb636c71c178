"""Per-gesture scores and confusion matrices of model A against APoc.

* ``per_gesture_table``: each gesture's frame-wise precision, recall and F1 (percent; per run the
  mean over its evaluation points, ``rnn_seg.tasks.task_metrics``), mean over the folds where
  they are defined (a gesture absent from a fold's test trials has no recall there, one never
  predicted no precision), with ``folds``, the folds whose test trials hold the gesture;
* ``confusion_figure``: the confusion matrices of the compared models side by side, summed over
  their runs (folds, seeds and evaluation points; ``metrics.json``'s ``confusion``) and
  normalised per row: row = true gesture, column = predicted, so the diagonal is each gesture's
  pooled recall; a gesture absent from every test trial is an empty row.

Both read the revised-annotation, bidirectional runs of the compared configurations (those of
``figures.COMPARED`` the grid ran). Runs finished before per-class scores were saved (an older
scores archive) have neither: ``write_per_class`` then writes nothing and says so in one line.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from jigsaws_tools.plots import PAGE_INCHES, figure_style  # noqa: E402
from rnn_seg.runs.folder import read_json, write_atomic  # noqa: E402

from ...grid.spec import RunKey  # noqa: E402
from ..runs.collect import KEY_COLUMNS  # noqa: E402
from ..statistics.paired import ConfigId  # noqa: E402
from .figures import COMPARED, label, save  # noqa: E402

TASK = "gesture"
SCORES = ("precision", "recall", "f1")
TABLE = "per_gesture.csv"
FIGURE = "confusion"


def compared_runs(runs: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The runs of each compared configuration (``figures.COMPARED``: revised labels,
    bidirectional) the grid ran.

    Args:
        runs: one row per run (``collect.run_rows``).

    Returns:
        ``{"A-fixed": its rows, ...}`` in ``figures.COMPARED`` order, without empty ones.
    """
    return {c: rows for c in COMPARED if not (rows := ConfigId.parse(c).select(runs)).empty}


def summed_confusion(grid_dir: Path, runs: pd.DataFrame, task: str = TASK
                     ) -> tuple[tuple[str, ...], np.ndarray] | None:
    """``(classes, [K, K] counts)`` of ``task`` summed over ``runs``' saved confusion matrices
    (rows true, columns predicted), or None when a run's ``metrics.json`` has none."""
    classes, total = None, None
    for row in runs[KEY_COLUMNS].itertuples(index=False):
        path = Path(grid_dir) / RunKey(*row).path() / "metrics.json"
        saved = read_json(path).get("confusion", {}).get(task)
        if saved is None or (classes is not None and tuple(saved["classes"]) != classes):
            return None
        classes = tuple(saved["classes"])
        counts = np.asarray(saved["counts"], dtype=np.int64)
        total = counts if total is None else total + counts
    return None if classes is None else (classes, total)


def per_gesture_table(folds: pd.DataFrame, configs: list[str], classes: tuple[str, ...]
                      ) -> pd.DataFrame:
    """One row per compared configuration and gesture: ``configuration``, ``gesture``,
    ``folds`` (folds whose test trials hold it) and the mean over folds of ``precision``,
    ``recall`` and ``f1`` (percent, NaN where no fold defines it).

    Args:
        folds: one row per configuration and fold (``collect.per_fold``) with the columns
            ``gesture_<score>_<gesture>``.
        configs: ``<variant>-<weighting>`` of the offline configurations tabulated.
        classes: the gestures, in class order.
    """
    rows = []
    for config in configs:
        mine = ConfigId.parse(config).select(folds)
        for gesture in classes:
            row = {"configuration": config, "gesture": gesture,
                   "folds": int(mine[f"{TASK}_recall_{gesture}"].notna().sum())}
            row.update({s: mine[f"{TASK}_{s}_{gesture}"].mean() for s in SCORES})
            rows.append(row)
    return pd.DataFrame(rows, columns=["configuration", "gesture", "folds", *SCORES])


def row_normalised(counts: np.ndarray) -> np.ndarray:
    """``[K, K]`` counts -> each row's share in percent; NaN rows where a class never occurs."""
    counts = np.asarray(counts, dtype=np.float64)
    totals = counts.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(totals > 0, 100.0 * counts / totals, np.nan)


@figure_style
def confusion_figure(matrices: dict[str, tuple[tuple[str, ...], np.ndarray]], out_dir: Path
                     ) -> list[Path]:
    """Row-normalised confusion matrices, one panel per configuration, two a row across a page,
    gesture names on both axes and each cell's percentage written in it.

    Args:
        matrices: ``{configuration: (classes, [K, K] counts)}`` (``summed_confusion``).
        out_dir: the folder written into.

    Returns:
        ``confusion.png`` and ``.pdf``.
    """
    columns = min(2, len(matrices))
    rows = math.ceil(len(matrices) / columns)
    fig, axes = plt.subplots(rows, columns, squeeze=False, constrained_layout=True,
                             figsize=(PAGE_INCHES if columns > 1 else PAGE_INCHES / 2 + 0.6,
                                      3.5 * rows))
    for ax in axes.flat[len(matrices):]:
        ax.remove()
    for ax, (config, (classes, counts)) in zip(axes.flat, matrices.items()):
        shares = row_normalised(counts)
        image = ax.imshow(np.ma.masked_invalid(shares), cmap="Blues", vmin=0, vmax=100)
        for (i, j), value in np.ndenumerate(shares):
            if np.isfinite(value) and value >= 0.5:
                ax.text(j, i, f"{value:.0f}", ha="center", va="center",
                        color="white" if value > 60 else "black")
        ticks = range(len(classes))
        ax.set_xticks(ticks, classes, rotation=90)
        ax.set_yticks(ticks, classes)
        ax.set_xlabel("predicted gesture")
        ax.set_title(f"{label(config)}\n{int(counts.sum())} predictions")
    for ax in axes[:, 0]:
        ax.set_ylabel("true gesture")
    fig.colorbar(image, ax=list(axes.flat[:len(matrices)]), shrink=0.8,
                 label="share of the true gesture [%]")
    return save(fig, out_dir, FIGURE)


def write_per_class(grid_dir: Path, runs: pd.DataFrame, folds: pd.DataFrame, out: Path,
                    figures: bool) -> list[Path]:
    """``per_gesture.csv`` in ``out`` and, with ``figures``, ``figures/confusion.png|pdf``, when
    every compared run saved its confusion matrix; else one line on stderr and nothing written.

    Args:
        grid_dir: the grid's folder.
        runs: one row per run (``collect.run_rows``).
        folds: one row per configuration and fold (``collect.per_fold``).
        out: the tables' folder.
        figures: also draw the confusion matrices.

    Returns:
        The paths written.
    """
    compared = compared_runs(runs)
    matrices = {c: summed_confusion(grid_dir, rows) for c, rows in compared.items()}
    if not matrices or None in matrices.values():
        print("note: no per-gesture table or confusion figure: the runs' metrics.json predate "
              "per-class scores (no confusion matrix)" if matrices else
              "note: no per-gesture table or confusion figure: the grid ran none of "
              f"{', '.join(COMPARED)} (revised, bidirectional)", file=sys.stderr)
        return []
    classes = next(iter(matrices.values()))[0]
    table = per_gesture_table(folds, list(matrices), classes)
    write_atomic(out / TABLE, table.to_csv(index=False, float_format="%.4f"))
    return [out / TABLE] + (confusion_figure(matrices, out / "figures") if figures else [])

