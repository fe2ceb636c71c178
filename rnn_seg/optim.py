"""SGD (optionally with momentum), global-norm clipping and a staircase learning-rate schedule.

Schedule lengths are counted in explicit units: ``"sweeps"`` (optimisation steps) or ``"epochs"``
(``ceil(train sequences / batch size)`` sweeps each).
"""
from __future__ import annotations

from typing import Sequence

import tensorflow as tf

from .config import UNITS, OptimConfig, Unit  # noqa: F401 (re-exported)


class SGD(tf.Module):
    """``v <- momentum * v + g;  w <- w - lr * v`` after clipping all gradients to one global
    norm."""

    def __init__(self, variables: Sequence[tf.Variable], momentum: float, clip_norm: float):
        super().__init__(name="sgd")
        self.momentum = momentum
        self.clip_norm = clip_norm
        self.velocities = [tf.Variable(tf.zeros_like(v), trainable=False, name="velocity")
                           for v in variables] if momentum else []

    def apply(self, grads: Sequence[tf.Tensor], variables: Sequence[tf.Variable],
              learning_rate: tf.Tensor) -> tf.Tensor:
        """Update ``variables`` in place.

        Args:
            grads: one float32 gradient per variable, in the order of ``variables``.
            variables: the variables this ``SGD`` was built with, in the same order (momentum).
            learning_rate: scalar float32, the sweep's learning rate.

        Returns:
            Scalar float32, the gradients' global norm before clipping.
        """
        clipped, norm = tf.clip_by_global_norm(grads, self.clip_norm)
        if self.momentum:
            for v, g, var in zip(self.velocities, clipped, variables):
                v.assign(self.momentum * v + g)
                var.assign_sub(learning_rate * v)
        else:
            for g, var in zip(clipped, variables):
                var.assign_sub(learning_rate * g)
        return norm
