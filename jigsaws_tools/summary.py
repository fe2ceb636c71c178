"""Per-trial summary of a release: frame counts and gesture / progress histograms at 30 Hz."""
from __future__ import annotations

import numpy as np
import pandas as pd

from .annotations import apply_amendments
from .gestures import UNLABELLED
from .progress import progress_labels
from .release import ReleaseIndex, frame_labels, read_kinematics, read_transcription


def release_summary(index: ReleaseIndex, version: str) -> pd.DataFrame:
    """One row per complete trial: frames, labelled frames, frames per gesture of the index's
    task (columns named as its gestures) and per progress stage (``P0``, ``P1``, ...)."""
    task = index.task
    rows = []
    for t in index.trials:
        n_frames = len(read_kinematics(t.kinematics))
        labels = frame_labels(read_transcription(t.transcription, n_frames, task), n_frames, task)
        labels, _ = apply_amendments(t.name, labels, version, task)
        labelled = labels[labels != UNLABELLED]
        progress = progress_labels(labelled, task)
        row = {"trial": t.name, "frames": n_frames, "labelled": len(labelled)}
        row.update(zip(task.gestures, np.bincount(labelled, minlength=task.num_gestures)))
        row.update(zip(task.stage_labels, np.bincount(progress, minlength=task.num_stages)))
        rows.append(row)
    return pd.DataFrame(rows).set_index("trial")
