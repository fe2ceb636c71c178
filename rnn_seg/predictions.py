"""One format for every predictions CSV: a training run's evaluation points, ``multitask-evaluate``,
``multitask-predict`` and streaming prediction.

A row is one time step of a recording, with a stated time base:

* ``frame``: 1-based frame number at the recording's own rate (30 Hz for JIGSAWS kinematics);
* ``time_s``: seconds since the recording's first frame, ``(frame - 1) / frame_hz``;
* ``sample``: 0-based index of the model's sample (5 Hz for JIGSAWS) whose prediction the row
  holds;

then per task ``<task>``: the predicted class *name* (a gesture such as ``G3``, a progress stage
such as ``push``; never a class index), ``<task>_true``: the labelled class name (evaluations
only), and the head's scores ``<task>_<column>`` (``Task.score_columns``, e.g. ``gesture_p_G3``).
An evaluation writes one row per scored sample (the samples its metrics count); a prediction one
row per frame (each frame holding the last sample at or before it), so every column of a
prediction is also in an evaluation.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import pandas as pd

from .tasks import Task


def prediction_table(tasks: Sequence[Task], outputs: dict[str, np.ndarray], samples: np.ndarray,
                     frames: np.ndarray, frame_hz: float,
                     labels: dict[str, np.ndarray] | None = None) -> pd.DataFrame:
    """The predictions of one recording in the common format (module docstring).

    Args:
        tasks: the model's tasks (decoding, class names, score columns).
        outputs: per task, raw head outputs ``[T, K]`` at the model's ``T`` samples.
        samples: ``[n]`` int64 sample index of each row, in ``0..T-1``.
        frames: ``[n]`` int64 1-based frame of each row, at ``frame_hz``.
        frame_hz: the rate of ``frames`` in Hz.
        labels: per task, the ``[n]`` int64 true class index of each row (evaluations), or None.

    Returns:
        ``n`` rows: ``frame``, ``time_s``, ``sample``, then per task ``<task>``, ``<task>_true``
        (with ``labels``) and its score columns.
    """
    frames = np.asarray(frames, dtype=np.int64)
    columns: dict[str, np.ndarray] = {"frame": frames, "time_s": (frames - 1) / frame_hz,
                                      "sample": np.asarray(samples, dtype=np.int64)}
    for t in tasks:
        names = np.asarray(t.class_names)
        columns[t.name] = names[t.decode(outputs[t.name])[samples]]
        if labels is not None:
            columns[f"{t.name}_true"] = names[labels[t.name]]
        columns.update(zip([f"{t.name}_{c}" for c in t.score_columns()],
                           t.scores(outputs[t.name])[samples].T))
    return pd.DataFrame(columns)


def prediction_csv(table: pd.DataFrame) -> str:
    """``prediction_table``'s text as every predictions CSV holds it (scores to 5 decimals)."""
    return table.to_csv(index=False, float_format="%.5f")
