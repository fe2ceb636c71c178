"""Progress heads: regression (MAE), classification (softmax) and ordered classification (sigmoid).

Each reads the encoder's shared features (``2H`` of the BiLSTM) through its own fully connected
layer (built by ``rnn_seg.model``); here are their targets, losses and decoding. Progress stages are
``0..K-1``, the task's (``TaskDefinition.stage_names``; for the paper's Suturing, the default:
reach, position, push, pull, drop), and the heads' class names are the stages' names.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import tensorflow as tf

from jigsaws_tools.progress import ordinal_decode, ordinal_encode
from jigsaws_tools.task_definition import SUTURING
from rnn_seg.tasks import SoftmaxClassification, Task, step_mean

from .config import ORDINAL_LOSSES, HeadConfig, OrdinalLoss  # noqa: F401 (re-exported)

PAPER_STAGES = SUTURING.stage_names


def stage_classes(stages: Sequence[str]) -> tuple[str, ...]:
    """Class names of the progress heads: the stages' names, in order (at least two)."""
    if len(stages) < 2:
        raise ValueError(f"progress needs at least 2 stages, not {len(stages)}")
    return tuple(stages)


class ProgressRegression(Task):
    """One linear output, mean absolute error over time steps; prediction = round, clip to
    ``0..num_stages-1``."""

    ordered = True

    def __init__(self, stages: Sequence[str] = PAPER_STAGES):
        super().__init__("progress", stage_classes(stages))

    @property
    def num_outputs(self) -> int:
        return 1

    def encode(self, labels):
        return labels[..., None].astype(np.float32)

    def loss(self, outputs, targets, mask=None):
        """``Task.loss``: the mean absolute error, in stages."""
        return step_mean(tf.abs(outputs - targets), mask)

    def scores(self, outputs):
        return outputs

    def score_columns(self):
        return ["value"]

    def decode(self, outputs):
        return np.clip(np.rint(outputs[..., 0]), 0, self.num_classes - 1).astype(np.int64)

    def scores_tf(self, outputs):
        return outputs

    def decode_tf(self, outputs):
        return tf.cast(tf.clip_by_value(tf.round(outputs[..., 0]), 0.0,
                                        float(self.num_classes - 1)), tf.int64)

    def extra_metrics(self, outputs: Sequence[np.ndarray], labels: Sequence[np.ndarray]
                      ) -> dict[str, float]:
        """``mae_normalised`` = 100 * MAE / (num_stages - 1) of the raw output (mean over
        sequences; the paper's 100 * MAE / 4 for Suturing), and of the rounded prediction
        (``mae_normalised_rounded``)."""
        span = self.num_classes - 1
        raw = [np.mean(np.abs(o[:, 0] - y)) for o, y in zip(outputs, labels)]
        rounded = [np.mean(np.abs(self.decode(o) - y)) for o, y in zip(outputs, labels)]
        return {"mae_normalised": float(100 * np.mean(raw) / span),
                "mae_normalised_rounded": float(100 * np.mean(rounded) / span)}


class ProgressClassification(SoftmaxClassification):
    """Softmax over the stages (five-way for Suturing) with mean cross-entropy."""

    ordered = True

    def __init__(self, stages: Sequence[str] = PAPER_STAGES):
        super().__init__("progress", stage_classes(stages))


class OrdinalProgress(Task):
    """One sigmoid output per stage (five for Suturing) on Cheng et al.'s cumulative targets;
    loss = binary cross-entropy summed (or averaged, ``reduction="mean"``) over the outputs,
    averaged over steps; decoded by the first output below 0.5 (see jigsaws_tools.progress)."""

    ordered = True

    def __init__(self, stages: Sequence[str] = PAPER_STAGES, reduction: OrdinalLoss = "sum"):
        super().__init__("progress", stage_classes(stages))
        self.reduction = reduction

    def encode(self, labels):
        return ordinal_encode(labels.reshape(-1), self.num_classes).reshape(labels.shape + (-1,))

    def loss(self, outputs, targets, mask=None):
        """``Task.loss``: binary cross-entropy summed or averaged over the outputs (above)."""
        per_output = tf.nn.sigmoid_cross_entropy_with_logits(targets, outputs)     # [B, T, K]
        if self.reduction == "sum":
            return step_mean(tf.reduce_sum(per_output, axis=-1), mask)
        return step_mean(per_output, mask)

    def scores(self, outputs):
        return 1.0 / (1.0 + np.exp(-outputs))

    def score_columns(self):
        """``y_<stage>``: the sigmoid output for "progress has reached this stage"."""
        return [f"y_{c}" for c in self.class_names]

    def decode(self, outputs):
        return ordinal_decode(self.scores(outputs))

    def scores_tf(self, outputs):
        return tf.sigmoid(outputs)

    def log_scores_tf(self, outputs):
        """log sigma of every output: "progress has reached this stage", in log-probability."""
        return tf.math.log_sigmoid(outputs)

    def decode_tf(self, outputs):
        """``ordinal_decode`` of the sigmoid outputs."""
        below = self.scores_tf(outputs) < 0.5
        first_below = tf.where(tf.reduce_any(below, axis=-1),
                               tf.argmax(tf.cast(below, tf.int32), axis=-1),
                               tf.cast(tf.shape(outputs)[-1], tf.int64))
        return tf.maximum(first_below - 1, 0)
