"""Progress heads: regression (MAE), classification (softmax) and ordered classification (sigmoid).

Each reads the shared ``2H`` BiLSTM features through its own fully connected layer (built by
``rnn_seg.model``); here are their targets, losses and decoding. Progress stages are 0-4.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import tensorflow as tf

from jigsaws_tools.progress import NUM_STAGES, ordinal_decode, ordinal_encode
from rnn_seg.tasks import SoftmaxClassification, Task, step_mean

STAGE_NAMES = tuple(f"P{k}" for k in range(NUM_STAGES))


class ProgressRegression(Task):
    """One linear output, mean absolute error over time steps; prediction = round, clip to 0..4."""

    ordered = True

    def __init__(self):
        super().__init__("progress", STAGE_NAMES)

    @property
    def num_outputs(self) -> int:
        return 1

    def encode(self, labels):
        return labels[..., None].astype(np.float32)

    def loss(self, outputs, targets, mask=None):
        return step_mean(tf.abs(outputs - targets), mask)

    def scores(self, outputs):
        return outputs

    def score_columns(self):
        return ["value"]

    def decode(self, outputs):
        return np.clip(np.rint(outputs[..., 0]), 0, NUM_STAGES - 1).astype(np.int64)

    def scores_tf(self, outputs):
        return outputs

    def decode_tf(self, outputs):
        return tf.cast(tf.clip_by_value(tf.round(outputs[..., 0]), 0, NUM_STAGES - 1), tf.int64)

    def extra_metrics(self, outputs: Sequence[np.ndarray], labels: Sequence[np.ndarray]
                      ) -> dict[str, float]:
        """``mae_normalised`` = 100 * MAE / 4 of the raw output (mean over sequences), and of the
        rounded prediction (``mae_normalised_rounded``)."""
        span = NUM_STAGES - 1
        raw = [np.mean(np.abs(o[:, 0] - y)) for o, y in zip(outputs, labels)]
        rounded = [np.mean(np.abs(self.decode(o) - y)) for o, y in zip(outputs, labels)]
        return {"mae_normalised": float(100 * np.mean(raw) / span),
                "mae_normalised_rounded": float(100 * np.mean(rounded) / span)}


class ProgressClassification(SoftmaxClassification):
    """Five-way softmax over stages with mean cross-entropy."""

    ordered = True

    def __init__(self):
        super().__init__("progress", STAGE_NAMES)


class OrdinalProgress(Task):
    """Five sigmoid outputs on Cheng et al.'s cumulative targets, mean binary cross-entropy over
    outputs and steps; decoded by the first output below 0.5 (see jigsaws_tools.progress)."""

    ordered = True

    def __init__(self):
        super().__init__("progress", STAGE_NAMES)

    def encode(self, labels):
        return ordinal_encode(labels.reshape(-1), self.num_classes).reshape(labels.shape + (-1,))

    def loss(self, outputs, targets, mask=None):
        return step_mean(tf.nn.sigmoid_cross_entropy_with_logits(targets, outputs), mask)

    def scores(self, outputs):
        return 1.0 / (1.0 + np.exp(-outputs))

    def score_columns(self):
        return [f"y{k}" for k in range(self.num_classes)]

    def decode(self, outputs):
        return ordinal_decode(self.scores(outputs))

    def scores_tf(self, outputs):
        return tf.sigmoid(outputs)

    def decode_tf(self, outputs):
        """``ordinal_decode`` of the sigmoid outputs."""
        below = self.scores_tf(outputs) < 0.5
        first_below = tf.where(tf.reduce_any(below, axis=-1),
                               tf.argmax(tf.cast(below, tf.int32), axis=-1),
                               tf.cast(tf.shape(outputs)[-1], tf.int64))
        return tf.maximum(first_below - 1, 0)
