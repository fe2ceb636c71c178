"""Action-based progress labels (van Amsterdam et al. 2020) and their three target encodings.

A task's progress grammar (``TaskDefinition.stages``) maps each essential gesture to a stage
0..K-1; for Suturing, the paper's: 0 = G1, G5; 1 = G2; 2 = G3; 3 = G6, G9, G10; 4 = G11. Adjustment
gestures (Suturing's G4 and G8) take the stage of the next essential gesture. A trailing adjustment
with no essential gesture after it keeps the stage of the last essential gesture before it (it
completes that stage); a trial made only of adjustments is stage 0. Progress repeats for each
cycle of the task (each throw of the suture).
"""
from __future__ import annotations

import numpy as np

from .gestures import UNLABELLED
from .task_definition import SUTURING, TaskDefinition


def progress_labels(gestures: np.ndarray, task: TaskDefinition = SUTURING) -> np.ndarray:
    """Progress stage per frame from gesture class indices.

    Args:
        gestures: ``[n]`` int class indices of ``task``'s vocabulary, ``UNLABELLED`` (-1) anywhere.
        task: whose progress grammar applies (default: the paper's Suturing).

    Returns:
        ``[n]`` int64 stages ``0..task.num_stages-1``; ``UNLABELLED`` where the gesture is
        unlabelled. Unlabelled frames are transparent: an adjustment looks past them to the next
        labelled essential gesture.
    """
    out = np.full(len(gestures), UNLABELLED, dtype=np.int64)
    labelled = np.flatnonzero(gestures != UNLABELLED)
    stages = task.stage_of_class[gestures[labelled]]
    stages = _fill(stages, backward=True)     # adjustments take the next essential stage
    stages = _fill(stages, backward=False)    # trailing adjustments keep the previous one
    stages[stages < 0] = 0                    # only adjustments at all
    out[labelled] = stages
    return out


def _fill(values: np.ndarray, backward: bool) -> np.ndarray:
    """Replace each -1 by the nearest non-negative value after it (backward) or before it."""
    v = values[::-1] if backward else values
    index = np.where(v >= 0, np.arange(len(v)), -1)
    np.maximum.accumulate(index, out=index)
    filled = np.where(index >= 0, v[np.maximum(index, 0)], -1)
    return filled[::-1] if backward else filled


def one_hot(progress: np.ndarray, num_stages: int = SUTURING.num_stages) -> np.ndarray:
    """``[T]`` stages -> ``[T, num_stages]`` float32 one-hot targets (classification)."""
    return np.eye(num_stages, dtype=np.float32)[progress]


def ordinal_encode(progress: np.ndarray, num_stages: int = SUTURING.num_stages) -> np.ndarray:
    """Cheng et al. (2008) cumulative targets: stage k -> ``t_j = 1`` for ``j <= k``, else 0.

    ``[T]`` stages -> ``[T, num_stages]`` float32; with 5 stages, stage 0 is ``[1, 0, 0, 0, 0]``
    and stage 4 all ones.
    """
    return (np.arange(num_stages)[None, :] <= progress[:, None]).astype(np.float32)


def ordinal_decode(outputs: np.ndarray) -> np.ndarray:
    """Sigmoid outputs ``[T, K]`` -> stages ``[T]``: (first index j with ``y_j < 0.5``) - 1.

    No output below 0.5 decodes to ``K - 1``; ``y_0 < 0.5`` (which no target has) decodes to 0.
    """
    below = outputs < 0.5
    first_below = np.where(below.any(axis=1), below.argmax(axis=1), outputs.shape[1])
    return np.maximum(first_below - 1, 0).astype(np.int64)
