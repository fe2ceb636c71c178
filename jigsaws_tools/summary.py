"""Per-trial summary of a release: row counts and gesture / progress histograms per recording row
(a 30 Hz frame in JIGSAWS)."""
from __future__ import annotations

import numpy as np
import pandas as pd

from .annotations import apply_amendments
from .gestures import UNLABELLED
from .progress import progress_labels
from .recording_format import JIGSAWS_FORMAT, RecordingFormat
from .release import ReleaseIndex, TrialFiles, frame_labels, read_recording, read_transcription
from .task_definition import TaskDefinition


def release_summary(index: ReleaseIndex, version: str) -> pd.DataFrame:
    """One row per complete trial: frames, labelled frames, frames per gesture of the index's
    task (columns named as its gestures) and per progress stage (columns named as its stages,
    e.g. ``reach``)."""
    task = index.task
    rows = []
    for t in index.trials:
        n_frames, labels = trial_labels(t, task, version, index.recording_format)
        labelled = labels[labels != UNLABELLED]
        progress = progress_labels(labelled, task)
        row = {"trial": t.name, "frames": n_frames, "labelled": len(labelled)}
        row.update(zip(task.gestures, np.bincount(labelled, minlength=task.num_gestures)))
        row.update(zip(task.stage_names, np.bincount(progress, minlength=task.num_stages)))
        rows.append(row)
    return pd.DataFrame(rows).set_index("trial")


def trial_labels(trial: TrialFiles, task: TaskDefinition, version: str,
                 recording_format: RecordingFormat = JIGSAWS_FORMAT) -> tuple[int, np.ndarray]:
    """A trial's row count (its recording in ``recording_format``) and its ``[n_rows]`` gesture
    class per row (a 30 Hz frame in JIGSAWS; ``UNLABELLED`` where the transcription says nothing)
    in annotation ``version``."""
    n_frames = len(read_recording(trial.kinematics, recording_format))
    labels = frame_labels(read_transcription(trial.transcription, n_frames, task), n_frames, task)
    labels, _ = apply_amendments(trial.name, labels, version, task, recording_format.rate_hz)
    return n_frames, labels
