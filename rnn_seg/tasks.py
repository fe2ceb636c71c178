"""Tasks: what a head predicts, its training targets, loss and decoding.

A task maps integer labels ``[T]`` per sequence to float targets ``[T, K]``, scores a head's raw
outputs ``[B, T, K]`` with a loss averaged over every time step of the sweep, and decodes outputs
``[T, K]`` back to integer labels ``[T]``.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import tensorflow as tf


class Task:
    """Base class; subclasses fix the encoding, loss and decoding."""

    #: Whether the classes are ordered stages (plotted as a line of truth vs prediction too).
    ordered = False

    def __init__(self, name: str, class_names: Sequence[str]):
        self.name = name
        self.class_names = tuple(class_names)

    @property
    def num_classes(self) -> int:
        return len(self.class_names)

    @property
    def num_outputs(self) -> int:
        return self.num_classes

    def encode(self, labels: np.ndarray) -> np.ndarray:
        """Integer labels ``[..., T]`` -> float32 targets ``[..., T, num_outputs]``."""
        raise NotImplementedError

    def loss(self, outputs: tf.Tensor, targets: tf.Tensor, mask: tf.Tensor | None = None
             ) -> tf.Tensor:
        """Scalar float32 mean loss over the steps where ``mask`` is set.

        Args:
            outputs: ``[B, T, K]`` float32 raw head outputs.
            targets: ``[B, T, num_outputs]`` float32 targets (``encode``).
            mask: ``[B, T]`` bool, the steps that count; None = every step.
        """
        raise NotImplementedError

    def scores(self, outputs: np.ndarray) -> np.ndarray:
        """Raw outputs ``[T, K]`` -> per-step scores written next to predictions (``[T, K]``)."""
        raise NotImplementedError

    def decode(self, outputs: np.ndarray) -> np.ndarray:
        """Raw outputs ``[T, K]`` -> integer labels ``[T]``."""
        raise NotImplementedError

    def scores_tf(self, outputs: tf.Tensor) -> tf.Tensor:
        """``scores`` as TensorFlow ops on ``[..., K]`` (for exported graphs; tests check that the
        two agree)."""
        raise NotImplementedError

    def decode_tf(self, outputs: tf.Tensor) -> tf.Tensor:
        """``decode`` as TensorFlow ops: ``[..., K]`` -> int64 ``[...]``."""
        raise NotImplementedError

    def log_scores_tf(self, outputs: tf.Tensor) -> tf.Tensor | None:
        """Log-probabilities ``[..., K]`` of the outputs, for losses on them (MS-TCN's
        smoothing); None for a head without probabilities (a regression)."""
        return None

    def score_columns(self) -> list[str]:
        return [f"p_{c}" for c in self.class_names]

    def extra_metrics(self, outputs: Sequence[np.ndarray], labels: Sequence[np.ndarray]
                      ) -> dict[str, float]:
        """Task-specific metrics beyond the segmentation ones (none by default)."""
        return {}


class SoftmaxClassification(Task):
    """Softmax over classes, mean cross-entropy, arg-max decoding (DiPietro's gesture head)."""

    def encode(self, labels):
        return np.eye(self.num_classes, dtype=np.float32)[labels]

    def loss(self, outputs, targets, mask=None):
        """``Task.loss``: the mean softmax cross-entropy."""
        return step_mean(tf.nn.softmax_cross_entropy_with_logits(targets, outputs), mask)

    def scores(self, outputs):
        e = np.exp(outputs - outputs.max(axis=-1, keepdims=True))
        return e / e.sum(axis=-1, keepdims=True)

    def decode(self, outputs):
        return np.argmax(outputs, axis=-1)

    def scores_tf(self, outputs):
        return tf.nn.softmax(outputs, axis=-1)

    def decode_tf(self, outputs):
        return tf.argmax(outputs, axis=-1)

    def log_scores_tf(self, outputs):
        return tf.nn.log_softmax(outputs, axis=-1)


def step_mean(values: tf.Tensor, mask: tf.Tensor | None) -> tf.Tensor:
    """Mean of per-step values ``[B, T]`` or ``[B, T, K]`` over the steps where ``mask`` ``[B, T]``
    (bool) is set, and over ``K``; None = the plain mean."""
    if mask is None:
        return tf.reduce_mean(values)
    values = tf.reshape(values, tf.concat([tf.shape(mask), [-1]], axis=0))        # [B, T, K]
    weight = tf.cast(mask, values.dtype)[..., None]
    count = tf.reduce_sum(weight) * tf.cast(tf.shape(values)[-1], values.dtype)
    return tf.reduce_sum(values * weight) / count


def task_metrics(task: Task, outputs: Sequence[np.ndarray], labels: Sequence[np.ndarray]
                 ) -> dict[str, float]:
    """Segmentation metrics of decoded outputs against labels, plus the task's own extras
    (``task_scores``' metrics; arguments as its)."""
    return task_scores(task, outputs, labels)[0]


def task_scores(task: Task, outputs: Sequence[np.ndarray], labels: Sequence[np.ndarray]
                ) -> tuple[dict[str, float], np.ndarray]:
    """The metrics of decoded outputs against labels and their confusion matrix, from one
    decoding.

    Args:
        task: decodes the outputs and names the classes.
        outputs: one ``[T_i, K]`` float32 array of raw head outputs per sequence.
        labels: the ``[T_i]`` int64 true labels, in the order of ``outputs``.

    Returns:
        ``(metrics, confusion)``. ``metrics``: ``segmentation_metrics``' scores; per class
        ``accuracy_<class>``, ``precision_<class>``, ``recall_<class>`` and ``f1_<class>``
        (frame-wise over the pooled steps, ``rnn_seg.metrics.class_scores``; NaN where undefined,
        e.g. a class absent from the labels); and ``task.extra_metrics``; all in percent except
        ``edit_distance`` (segments). ``confusion``: ``[K, K]`` int64 counts of (true, decoded)
        class pairs over every step (``rnn_seg.metrics.confusion_matrix``; rows true, columns
        predicted, in ``task.class_names`` order).
    """
    from .metrics import class_scores, confusion_matrix, segmentation_metrics

    preds = [task.decode(o) for o in outputs]
    metrics = segmentation_metrics(preds, labels)
    confusion = confusion_matrix(preds, labels, task.num_classes)
    precision, recall, f1 = class_scores(confusion)
    for kind, values in (("accuracy", recall), ("precision", precision), ("recall", recall),
                         ("f1", f1)):          # a class's accuracy is its recall
        metrics.update({f"{kind}_{c}": float(v) for c, v in zip(task.class_names, values)})
    metrics.update(task.extra_metrics(outputs, labels))
    return metrics, confusion
