"""A time-only progress model (de Boer et al., ICCVW 2023): a trial's progress stage read from
its time alone, fitted on the training folds of each LOUO fold and scored on the held-out user
with the progress heads' metrics.

* ``offline`` (beside the bidirectional models, which see the whole trial): the stage at relative
  time ``(t + 1/2) / T`` of a trial of ``T`` samples is the stage most frequent at that relative
  time in the training trials (``BINS`` equal bins of relative time, each training sample in
  its bin);
* ``online`` (beside the forward models): the stage at elapsed time ``t`` (in samples, 5 Hz) is
  the stage most frequent at that elapsed time among the training trials still running then; past
  the longest training trial, the last stage.

Ties go to the earlier stage. Scores: ``accuracy``, ``edit``, ``f1@10`` (per-trial means,
``rnn_seg.metrics``) and ``mae``: ``100 * mean |stage - true stage| / (K - 1)``, the paper's
normalised MAE, K stages. Its per-fold scores are derived numbers a scores archive keeps
(``multitask.grid.archive``), so that its tables need no labels; the rows of the tables:
``multitask.evidence.statistics.time_baseline``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Literal, Sequence

import numpy as np
import pandas as pd

Mode = Literal["offline", "online"]
MODES = ("offline", "online")
#: Bins of relative time of the offline predictor (1 % of a trial each).
BINS = 100


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


def release_fold_scores(release, annotations: str) -> pd.DataFrame:
    """The offline ``fold_scores`` on the folds of ``release`` (``multitask.grid.folder.
    GridRelease``: its folder, task, recording format and folds; all the release's users when it
    names none) with ``annotations``; ``OSError`` when its folder holds no such release (a
    synthetic one is never written in its place)."""
    from jigsaws_tools.dataset import DataConfig, load_dataset
    from jigsaws_tools.recording_format import load_format
    from jigsaws_tools.task_definition import load_task

    recording_format = load_format(release.format)       # the release's in older records
    if not (Path(release.folder) / recording_format.transcriptions).is_dir():
        raise OSError(f"the release {release.folder} is not here")
    dataset = load_dataset(DataConfig(str(release.folder), annotations=annotations,
                                      task=load_task(release.task),
                                      recording_format=recording_format))
    return fold_scores(dataset, release.folds or list(dataset.users), "offline")
