"""SGD (optionally with momentum), RMSprop, Adam, global-norm clipping and a staircase schedule.

SGD is the paper's (and DiPietro's). RMSprop and Adam train the temporal-convolution encoders as
their references do (``rnn_seg.encoders.config.SCHEDULES``), with those references' constants:
RMSprop as Keras's (``rho`` 0.9, ``epsilon`` 1e-8; Lea et al.'s ED-TCN), Adam as PyTorch's
(``beta_1`` 0.9, ``beta_2`` 0.999, ``epsilon`` 1e-8, bias-corrected; Farha & Gall's MS-TCN).

Schedule lengths are counted in explicit units: ``"sweeps"`` (optimisation steps) or ``"epochs"``
(``ceil(train sequences / batch size)`` sweeps each).
"""
from __future__ import annotations

from typing import Sequence

import tensorflow as tf

from .config import UNITS, OptimConfig, Unit  # noqa: F401 (re-exported)

RMSPROP_RHO, RMSPROP_EPSILON = 0.9, 1e-8
ADAM_BETAS, ADAM_EPSILON = (0.9, 0.999), 1e-8


class SGD(tf.Module):
    """``v <- momentum * v + g;  w <- w - lr * v`` after clipping all gradients to one global
    norm (``clip_norm``; 0 = none)."""

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
        clipped, norm = clip(grads, self.clip_norm)
        if self.momentum:
            for v, g, var in zip(self.velocities, clipped, variables):
                v.assign(self.momentum * v + g)
                var.assign_sub(learning_rate * v)
        else:
            for g, var in zip(clipped, variables):
                var.assign_sub(learning_rate * g)
        return norm


def clip(grads: Sequence[tf.Tensor], clip_norm: float) -> tuple[list[tf.Tensor], tf.Tensor]:
    """``(grads clipped to the global norm clip_norm, their norm before)``; 0 = no clipping."""
    if clip_norm:
        clipped, norm = tf.clip_by_global_norm(grads, clip_norm)
        return clipped, norm
    return list(grads), tf.linalg.global_norm(grads)


class RMSprop(tf.Module):
    """``a <- rho a + (1 - rho) g^2;  w <- w - lr g / (sqrt(a) + epsilon)`` (Keras's RMSprop)."""

    def __init__(self, variables: Sequence[tf.Variable], clip_norm: float):
        super().__init__(name="rmsprop")
        self.clip_norm = clip_norm
        self.mean_squares = [tf.Variable(tf.zeros_like(v), trainable=False, name="mean_square")
                             for v in variables]

    def apply(self, grads: Sequence[tf.Tensor], variables: Sequence[tf.Variable],
              learning_rate: tf.Tensor) -> tf.Tensor:
        """Update ``variables`` in place; arguments and result as ``SGD.apply``'s."""
        clipped, norm = clip(grads, self.clip_norm)
        for a, g, var in zip(self.mean_squares, clipped, variables):
            a.assign(RMSPROP_RHO * a + (1.0 - RMSPROP_RHO) * g * g)
            var.assign_sub(learning_rate * g / (tf.sqrt(a) + RMSPROP_EPSILON))
        return norm


class Adam(tf.Module):
    """Kingma & Ba's Adam with bias correction (PyTorch's ``torch.optim.Adam``)::

        m <- b1 m + (1 - b1) g;  v <- b2 v + (1 - b2) g^2
        w <- w - lr (m / (1 - b1^t)) / (sqrt(v / (1 - b2^t)) + epsilon)
    """

    def __init__(self, variables: Sequence[tf.Variable], clip_norm: float):
        super().__init__(name="adam")
        self.clip_norm = clip_norm
        self.steps = tf.Variable(0.0, trainable=False, name="steps")
        self.firsts = [tf.Variable(tf.zeros_like(v), trainable=False, name="first_moment")
                       for v in variables]
        self.seconds = [tf.Variable(tf.zeros_like(v), trainable=False, name="second_moment")
                        for v in variables]

    def apply(self, grads: Sequence[tf.Tensor], variables: Sequence[tf.Variable],
              learning_rate: tf.Tensor) -> tf.Tensor:
        """Update ``variables`` in place; arguments and result as ``SGD.apply``'s."""
        clipped, norm = clip(grads, self.clip_norm)
        b1, b2 = ADAM_BETAS
        t = self.steps.assign_add(1.0)
        first_bias, second_bias = 1.0 - b1 ** t, 1.0 - b2 ** t
        for m, v, g, var in zip(self.firsts, self.seconds, clipped, variables):
            m.assign(b1 * m + (1.0 - b1) * g)
            v.assign(b2 * v + (1.0 - b2) * g * g)
            var.assign_sub(learning_rate * (m / first_bias)
                           / (tf.sqrt(v / second_bias) + ADAM_EPSILON))
        return norm


def build_optimizer(variables: Sequence[tf.Variable], optim: OptimConfig) -> tf.Module:
    """The optimiser ``optim`` names, for ``variables`` (its ``apply`` updates them)."""
    if optim.optimizer == "rmsprop":
        return RMSprop(variables, optim.clip_norm)
    if optim.optimizer == "adam":
        return Adam(variables, optim.clip_norm)
    return SGD(variables, optim.momentum, optim.clip_norm)
