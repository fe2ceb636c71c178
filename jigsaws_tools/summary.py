"""Per-trial summary of a release: frame counts and gesture / progress histograms at 30 Hz."""
from __future__ import annotations

import numpy as np
import pandas as pd

from .annotations import apply_amendments
from .gestures import GESTURES, UNLABELLED
from .progress import NUM_STAGES, progress_labels
from .release import ReleaseIndex, frame_labels, read_kinematics, read_transcription


def release_summary(index: ReleaseIndex, version: str) -> pd.DataFrame:
    """One row per complete trial: frames, labelled frames, frames per gesture and per stage."""
    rows = []
    for t in index.trials:
        n_frames = len(read_kinematics(t.kinematics))
        labels = frame_labels(read_transcription(t.transcription, n_frames), n_frames)
        labels, _ = apply_amendments(t.name, labels, version)
        labelled = labels[labels != UNLABELLED]
        progress = progress_labels(labelled)
        row = {"trial": t.name, "frames": n_frames, "labelled": len(labelled)}
        row.update(zip(GESTURES, np.bincount(labelled, minlength=len(GESTURES))))
        row.update((f"P{k}", c) for k, c in enumerate(np.bincount(progress, minlength=NUM_STAGES)))
        rows.append(row)
    return pd.DataFrame(rows).set_index("trial")
