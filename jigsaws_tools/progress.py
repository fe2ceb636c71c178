"""Action-based progress labels (van Amsterdam et al. 2020) and their three target encodings.

Stages within one stitch: 0 = G1, G5; 1 = G2; 2 = G3; 3 = G6, G9, G10; 4 = G11. The adjustment
gestures G4 and G8 take the stage of the next essential gesture. A trailing G4/G8 with no essential
gesture after it keeps the stage of the last essential gesture before it (it completes that stage);
a trial made only of adjustments is stage 0. Progress repeats for each throw of the suture.
"""
from __future__ import annotations

import numpy as np

from .gestures import GESTURE_INDEX, UNLABELLED

NUM_STAGES = 5
ESSENTIAL_STAGE: dict[str, int] = {
    "G1": 0, "G5": 0, "G2": 1, "G3": 2, "G6": 3, "G9": 3, "G10": 3, "G11": 4,
}
ADJUSTMENTS = ("G4", "G8")

# Class index -> stage; adjustments -> -1 (resolved from their neighbours).
_STAGE_OF_CLASS = np.full(len(GESTURE_INDEX), -1, dtype=np.int64)
for _name, _stage in ESSENTIAL_STAGE.items():
    _STAGE_OF_CLASS[GESTURE_INDEX[_name]] = _stage


def progress_labels(gestures: np.ndarray) -> np.ndarray:
    """Progress stage per frame from gesture class indices.

    Args:
        gestures: ``[n]`` int gesture class indices (0-9), ``UNLABELLED`` (-1) allowed anywhere.

    Returns:
        ``[n]`` int64 stages 0-4; ``UNLABELLED`` where the gesture is unlabelled. Unlabelled frames
        are transparent: an adjustment looks past them to the next labelled essential gesture.
    """
    out = np.full(len(gestures), UNLABELLED, dtype=np.int64)
    labelled = np.flatnonzero(gestures != UNLABELLED)
    stages = _STAGE_OF_CLASS[gestures[labelled]]
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


def one_hot(progress: np.ndarray, num_stages: int = NUM_STAGES) -> np.ndarray:
    """``[T]`` stages -> ``[T, num_stages]`` float32 one-hot targets (classification)."""
    return np.eye(num_stages, dtype=np.float32)[progress]


def ordinal_encode(progress: np.ndarray, num_stages: int = NUM_STAGES) -> np.ndarray:
    """Cheng et al. (2008) cumulative targets: stage k -> ``t_j = 1`` for ``j <= k``, else 0.

    ``[T]`` stages -> ``[T, num_stages]`` float32; stage 0 is ``[1, 0, 0, 0, 0]``, stage 4 all ones.
    """
    return (np.arange(num_stages)[None, :] <= progress[:, None]).astype(np.float32)


def ordinal_decode(outputs: np.ndarray) -> np.ndarray:
    """Sigmoid outputs ``[T, K]`` -> stages ``[T]``: (first index j with ``y_j < 0.5``) - 1.

    No output below 0.5 decodes to ``K - 1``; ``y_0 < 0.5`` (which no target has) decodes to 0.
    """
    below = outputs < 0.5
    first_below = np.where(below.any(axis=1), below.argmax(axis=1), outputs.shape[1])
    return np.maximum(first_below - 1, 0).astype(np.int64)
