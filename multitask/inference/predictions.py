"""A model's predictions for one recording: per 5 Hz sample, per row of the recording (a 30 Hz
frame in JIGSAWS), as CSV and ribbons.

The network sees one sample per ``f`` rows (5 Hz; ``f = 6`` for JIGSAWS's 30 Hz frames,
``jigsaws_tools.preprocessing.decimation`` for another rate). Each row takes the prediction of
the last sample at or before it (a zero-order hold: sample k, taken at row ``k f + 1``, stands
for rows ``k f + 1 .. k f + f``), which is also what a streaming model has output when that row
arrives. ``hold`` maps rows to samples.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from jigsaws_tools.plots import Ribbon, plot_ribbons, task_colours
from jigsaws_tools.release import KINEMATICS_HZ
from rnn_seg.predictions import prediction_csv, prediction_table
from rnn_seg.runs.folder import write_atomic
from rnn_seg.tasks import Task


def hold(sample_frames: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Index of the last sample at or before each frame.

    Args:
        sample_frames: ``[T]`` increasing 1-based 30 Hz frames of the samples.
        frames: ``[n]`` 1-based 30 Hz frames, none before ``sample_frames[0]``.

    Returns:
        ``[n]`` int64 sample indices.
    """
    index = np.searchsorted(sample_frames, frames, side="right") - 1
    if len(index) and index.min() < 0:
        raise ValueError(f"frame {frames[np.argmin(index)]} precedes the first sample "
                         f"(frame {sample_frames[0]})")
    return index.astype(np.int64)


@dataclass(frozen=True)
class RecordingPrediction:
    """Predictions of every task for one recording of ``n_frames`` frames at ``frame_hz`` (the
    release's 30 Hz, or its recording format's rate).

    ``outputs``: raw head outputs ``[T, K_task]`` per task at the 5 Hz samples, taken at the
    1-based frames ``sample_frames`` ``[T]``; ``sample_hz``: their rate.
    """

    tasks: tuple[Task, ...]
    outputs: dict[str, np.ndarray]
    sample_frames: np.ndarray
    n_frames: int
    sample_hz: float
    frame_hz: float = KINEMATICS_HZ

    @property
    def frames(self) -> np.ndarray:
        """``[n_frames]`` 1-based 30 Hz frame numbers."""
        return np.arange(1, self.n_frames + 1, dtype=np.int64)

    @property
    def frame_samples(self) -> np.ndarray:
        """``[n_frames]`` index of the sample whose prediction each frame takes (``hold``)."""
        return hold(self.sample_frames, self.frames)

    def task(self, name: str) -> Task:
        for t in self.tasks:
            if t.name == name:
                return t
        raise KeyError(f"no task {name!r}; the model predicts "
                       f"{', '.join(t.name for t in self.tasks)}")

    def sample_labels(self, name: str) -> np.ndarray:
        """``[T]`` decoded class indices of task ``name`` at the samples."""
        return self.task(name).decode(self.outputs[name])

    def labels(self, name: str) -> np.ndarray:
        """``[n_frames]`` decoded class indices of task ``name`` per frame (into the task's
        ``class_names``; ``label_names`` gives the names)."""
        return self.sample_labels(name)[self.frame_samples]

    def label_names(self, name: str) -> np.ndarray:
        """``[n_frames]`` the class name of each frame's decoded class (``labels``): a gesture
        such as ``G3``, a progress stage such as ``reach``, as the predictions CSV writes them."""
        return np.asarray(self.task(name).class_names)[self.labels(name)]

    def scores(self, name: str) -> np.ndarray:
        """``[n_frames, K]`` scores of task ``name`` per frame (``Task.scores``: class
        probabilities, ordinal sigmoid outputs or the regressed value)."""
        return self.task(name).scores(self.outputs[name])[self.frame_samples]

    def table(self) -> pd.DataFrame:
        """One row per frame (at ``frame_hz``) in the format of every predictions CSV
        (``rnn_seg.predictions``): ``frame``, ``time_s``, ``sample``, then per task the predicted
        class name (a gesture, a progress stage) and its score columns ``<task>_<column>``."""
        return prediction_table(self.tasks, self.outputs, self.frame_samples, self.frames,
                                self.frame_hz)

    def write(self, folder: Path, name: str, title: str, plot: bool = True) -> list[Path]:
        """Write the predictions of this recording; returns the paths written.

        Args:
            folder: output folder.
            name: file name stem: ``<name>.csv`` (``table``) and ``<name>.png``.
            title: the plot's title.
            plot: also draw ``<name>.png`` (one ribbon per task at the samples).
        """
        csv = Path(folder) / f"{name}.csv"
        write_atomic(csv, prediction_csv(self.table()))
        if not plot:
            return [csv]
        return [csv, plot_predictions(self, Path(folder) / f"{name}.png", title)]


def plot_predictions(prediction: RecordingPrediction, path: Path, title: str) -> Path:
    """Ribbons of every task's predicted labels at the samples, over the recording's time in
    seconds (from its frames at ``frame_hz``).

    Args:
        prediction: the recording's predictions.
        path: the PNG written (folders created).
        title: the figure's title.

    Returns:
        ``path``.
    """
    times = (prediction.sample_frames - 1) / prediction.frame_hz
    return plot_ribbons([Ribbon(t.name, prediction.sample_labels(t.name), times, t.class_names,
                                task_colours(t.num_classes, t.ordered))
                         for t in prediction.tasks], path, title)

