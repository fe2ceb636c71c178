"""The time-only progress rows of the tables (de Boer et al., ICCVW 2023): the per-fold scores of
a trial's progress stage read from its time alone (``multitask.models.time_baseline``), as a row
beside the progress heads.

``time_baseline_rows`` adds the offline rows to a table of progress metrics: from the scores a
grid's scores archive keeps (``multitask.grid.archive``), computed from the grid's release when
it keeps none or when a release is given (``--data-dir``); without either, a note says so.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

#: The rows' labels in the tables.
LABELS = {"offline": "Time only (t/T)", "online": "Time only (elapsed)"}


def chance_accuracy(labels: Sequence[np.ndarray]) -> float:
    """Accuracy in percent of always predicting the most frequent label of ``labels`` (pooled
    over every sample of every ``[T_i]`` int array)."""
    pooled = np.concatenate(labels)
    return 100.0 * np.bincount(pooled).max() / len(pooled)


def time_baseline_rows(grid_dir: Path, table, columns: Sequence[str],
                       data_dir: Path | None = None) -> pd.DataFrame:
    """The offline baseline's rows for a comparison table of progress metrics (``table``, a
    ``tables.PaperTable``; ``columns`` its frame's): mean and std over the grid's folds on the
    table's annotations (``grid_fold_scores``). Empty when the table reports no progress or its
    direction is online (no such table yet), and, with a note, when they are not known."""
    metrics = [m for m in table.metrics if m.startswith("progress_") and m != "progress_mae_raw"]
    if not metrics or table.direction != "bidirectional":
        return pd.DataFrame(columns=list(columns))
    folds = grid_fold_scores(Path(grid_dir), table.annotations, table.name, data_dir)
    if folds is None:
        return pd.DataFrame(columns=list(columns))
    rows = [{"model": LABELS["offline"], "config": "time-offline", "metric": m,
             "left_mean": float(folds[m].mean()), "left_std": float(folds[m].std(ddof=1)),
             "right_mean": math.nan, "right_std": math.nan, "diff": math.nan,
             "folds": len(folds)}
            for m in metrics]
    return pd.DataFrame(rows, columns=list(columns))


def grid_fold_scores(grid_dir: Path, annotations: str, table: str,
                     data_dir: Path | None = None) -> pd.DataFrame | None:
    """The offline baseline's per-fold scores (``time_baseline.fold_scores``) on the folds of the
    grid in ``grid_dir`` with ``annotations``: computed from the release in ``data_dir`` when
    given; else as the grid's scores archive keeps them; else computed from the release its spec
    records. None, with a note naming ``table`` (the table that would hold the row), when none
    of these can be had."""
    from ...grid.archive import archived_time_only
    from ...grid.folder import grid_release, read_record
    from ...models.time_baseline import release_fold_scores

    kept = archived_time_only(grid_dir, annotations) if data_dir is None else None
    if kept is not None:
        return kept
    try:
        return release_fold_scores(grid_release(read_record(grid_dir) or {}, data_dir),
                                   annotations)
    except (OSError, ValueError) as error:
        print(f"note: no time-only progress row in {table}: the grid's data cannot be "
              f"read ({error}) and its archive keeps no time-only scores", file=sys.stderr)
        return None


def with_time_baseline(frame: pd.DataFrame, grid_dir: Path, table,
                       data_dir: Path | None = None) -> pd.DataFrame:
    """``frame`` (a comparison table, ``tables.paper_comparison``) with the time-only rows
    (``time_baseline_rows``; ``data_dir``: the grid's release, if given) after its models' rows
    when one of them reports progress."""
    if not frame.metric.str.startswith("progress_").any():
        return frame
    extra = time_baseline_rows(grid_dir, table, frame.columns, data_dir)
    if extra.empty:
        return frame
    return pd.concat([frame, extra], ignore_index=True)
