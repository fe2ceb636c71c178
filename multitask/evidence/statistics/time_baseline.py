"""A time-only progress baseline (de Boer et al., ICCVW 2023): a trial's progress stage read from
its time alone, as a row beside the progress heads.

de Boer et al. found that learned surgical progress predictors often do not beat one that only
counts time. Here the predictor is fitted on the training folds of each LOUO fold and scored on
the held-out user with the progress heads' metrics:

* ``offline`` (beside the bidirectional models, which see the whole trial): the stage at relative
  time ``(t + 1/2) / T`` of a trial of ``T`` samples is the stage most frequent at that relative
  time in the training trials (``BINS`` equal bins of relative time, each training sample in
  its bin);
* ``online`` (beside the forward models): the stage at elapsed time ``t`` (in samples, 5 Hz) is
  the stage most frequent at that elapsed time among the training trials still running then; past
  the longest training trial, the last stage.

Ties go to the earlier stage. Scores: ``accuracy``, ``edit``, ``f1@10`` (per-trial means,
``rnn_seg.metrics``) and ``mae``: ``100 * mean |stage - true stage| / (K - 1)``, the paper's
normalised MAE, K stages. ``time_baseline_rows`` adds the offline rows to a table of progress
metrics when the grid's data can be read (the labels are needed; the runs' archive holds none).
"""
from __future__ import annotations

import math

import sys
from pathlib import Path
from typing import Literal, Sequence

import numpy as np
import pandas as pd

Mode = Literal["offline", "online"]
MODES = ("offline", "online")
#: Bins of relative time of the offline predictor (1 % of a trial each).
BINS = 100
#: The rows' labels in the tables.
LABELS = {"offline": "Time only (t/T)", "online": "Time only (elapsed)"}


def chance_accuracy(labels: Sequence[np.ndarray]) -> float:
    """Accuracy in percent of always predicting the most frequent label of ``labels`` (pooled
    over every sample of every ``[T_i]`` int array)."""
    pooled = np.concatenate(labels)
    return 100.0 * np.bincount(pooled).max() / len(pooled)


def _majority(counts: np.ndarray) -> np.ndarray:
    """``[N, K]`` counts -> ``[N]`` the most frequent stage per row (ties: the earlier); a row
    without counts takes the nearest earlier row's stage (the first rows: the first counted)."""
    counted = np.flatnonzero(counts.sum(axis=1))
    nearest = counted[np.maximum(np.searchsorted(counted, np.arange(len(counts)), "right") - 1, 0)]
    return np.argmax(counts[nearest], axis=1)


class TimeBaseline:
    """The stage per bin of (relative or elapsed) time, fitted on training trials' stages."""

    def __init__(self, mode: Mode, stages: np.ndarray):
        self.mode, self.stages = mode, stages      # [bins] stage per bin

    @classmethod
    def fit(cls, progress: Sequence[np.ndarray], num_stages: int, mode: Mode) -> TimeBaseline:
        """Fit on training trials' stages ``[T_i]`` (ints in ``0..num_stages-1``)."""
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)} (got {mode!r})")
        size = BINS if mode == "offline" else max(len(y) for y in progress)
        counts = np.zeros((size, num_stages), int)
        for y in progress:
            np.add.at(counts, (cls._bins(mode, len(y), size), y), 1)
        stages = _majority(counts)
        if mode == "online":
            stages = np.append(stages, num_stages - 1)       # past the longest trial
        return cls(mode, stages)

    @staticmethod
    def _bins(mode: Mode, length: int, size: int) -> np.ndarray:
        """``[length]`` the bin of every sample of a trial of ``length`` samples."""
        t = np.arange(length)
        if mode == "offline":
            return np.minimum(((t + 0.5) / length * size).astype(int), size - 1)
        return np.minimum(t, size)

    def predict(self, length: int) -> np.ndarray:
        """``[length]`` predicted stages of a trial of ``length`` samples (online: of its first
        ``length`` samples, whatever follows)."""
        size = BINS if self.mode == "offline" else len(self.stages) - 1
        return self.stages[self._bins(self.mode, length, size)]


def scores(preds: Sequence[np.ndarray], trues: Sequence[np.ndarray], num_stages: int
           ) -> dict[str, float]:
    """The progress heads' metrics of predicted stages against the true ones (module docstring)."""
    from rnn_seg.metrics import segmentation_metrics

    metrics = segmentation_metrics(preds, trues)
    mae = np.mean([np.mean(np.abs(p - y)) for p, y in zip(preds, trues)])
    return {"accuracy": metrics["accuracy"], "edit": metrics["edit"],
            "f1@10": metrics["f1@10"], "mae": float(100 * mae / (num_stages - 1))}


def fold_scores(dataset, users: Sequence[str], mode: Mode) -> pd.DataFrame:
    """One row per LOUO fold (``fold``, ``progress_<metric>``): the baseline fitted on the other
    users' trials of ``dataset`` (``jigsaws_tools.dataset.Dataset``), scored on the fold's."""
    stages = len(dataset.config.task.stage_names)
    rows = []
    for user in users:
        train, test = dataset.louo_split(user)
        model = TimeBaseline.fit([t.progress for t in train], stages, mode)
        got = scores([model.predict(len(t.progress)) for t in test],
                     [t.progress for t in test], stages)
        rows.append({"fold": user, **{f"progress_{k}": v for k, v in got.items()}})
    return pd.DataFrame(rows)


def time_baseline_rows(grid_dir: Path, table, columns: Sequence[str]) -> pd.DataFrame:
    """The offline baseline's rows for a comparison table of progress metrics (``table``, a
    ``tables.PaperTable``; ``columns`` its frame's): mean and std over the grid's folds on the
    table's annotations. Empty when the table reports no progress or its direction is online (no
    such table yet), and, with a note, when the grid's data cannot be read."""
    metrics = [m for m in table.metrics if m.startswith("progress_") and m != "progress_mae_raw"]
    if not metrics or table.direction != "bidirectional":
        return pd.DataFrame(columns=list(columns))
    folds = grid_fold_scores(Path(grid_dir), table.annotations, table.name)
    if folds is None:
        return pd.DataFrame(columns=list(columns))
    rows = [{"model": LABELS["offline"], "config": "time-offline", "metric": m,
             "left_mean": float(folds[m].mean()), "left_std": float(folds[m].std(ddof=1)),
             "right_mean": math.nan, "right_std": math.nan, "diff": math.nan,
             "folds": len(folds)}
            for m in metrics]
    return pd.DataFrame(rows, columns=list(columns))


def grid_fold_scores(grid_dir: Path, annotations: str, table: str) -> pd.DataFrame | None:
    """The offline baseline's ``fold_scores`` on the folds of the grid in ``grid_dir``, fitted on
    its recorded release with ``annotations``; None, with a note naming ``table`` (the table that
    would hold the row), when that release cannot be read here."""
    try:
        dataset, users = _grid_data(Path(grid_dir), annotations)
    except (OSError, ValueError) as error:
        print(f"note: no time-only progress row in {table}: the grid's data cannot be "
              f"read ({error})", file=sys.stderr)
        return None
    return fold_scores(dataset, users, "offline")


def _grid_data(grid_dir: Path, annotations: str):
    """``(dataset, LOUO folds)`` of a grid: its record's data folder and task, the folds its runs
    hold; ``OSError`` when that folder is not here (or names the synthetic release, which a table
    does not write)."""
    from jigsaws_tools.dataset import DataConfig, load_dataset
    from jigsaws_tools.recording_format import load_format
    from jigsaws_tools.task_definition import load_task

    from ...grid.folder import read_record

    record = read_record(grid_dir) or {}
    spec = record.get("spec", {})
    task = load_task(spec.get("task") or "Suturing")
    recording_format = load_format(spec.get("format"))       # the release's in older records
    recorded = spec.get("data_dir")
    data_dir = Path(recorded) if recorded and recorded != "synthetic" else None
    if data_dir is None or not (data_dir / recording_format.transcriptions).is_dir():
        # never another release in its place, and no synthetic one written by a table
        raise OSError(f"the release the grid records ({recorded or 'none'}) is not here")
    users = sorted({Path(run).name for run in record.get("runs", [])})
    dataset = load_dataset(DataConfig(str(data_dir), annotations=annotations, task=task,
                                      recording_format=recording_format))
    return dataset, users or list(dataset.users)


def with_time_baseline(frame: pd.DataFrame, grid_dir: Path, table) -> pd.DataFrame:
    """``frame`` (a comparison table, ``tables.paper_comparison``) with the time-only rows
    (``time_baseline_rows``) after its models' rows when one of them reports progress."""
    if not frame.metric.str.startswith("progress_").any():
        return frame
    extra = time_baseline_rows(grid_dir, table, frame.columns)
    if extra.empty:
        return frame
    return pd.concat([frame, extra], ignore_index=True)
