"""Fully connected output layer applied at every time step."""
from __future__ import annotations

from typing import NamedTuple

import tensorflow as tf


class DenseParams(NamedTuple):
    """Weights of a dense layer, as variables or (stacked) tensors."""

    W: tf.Tensor        # [D, K]
    b: tf.Tensor        # [K]


class Dense(tf.Module):
    """``[B, T, D]`` -> ``[B, T, K]`` linear map; weights uniform in ``[-init_scale, init_scale]``.

    The bias starts uniform too, as in DiPietro's logits layer (``b`` there takes the scope's
    uniform initializer), or zero with ``zero_bias`` (Keras's ``Dense``; then no draw from
    ``rng`` for it).
    """

    def __init__(self, input_size: int, output_size: int, init_scale: float,
                 rng: tf.random.Generator, name: str, zero_bias: bool = False):
        super().__init__(name=name)
        self.W = tf.Variable(rng.uniform([input_size, output_size], -init_scale, init_scale),
                             name="W")
        self.b = tf.Variable(tf.zeros([output_size]) if zero_bias
                             else rng.uniform([output_size], -init_scale, init_scale), name="b")

    def params(self) -> DenseParams:
        return DenseParams(self.W, self.b)

    def __call__(self, features: tf.Tensor) -> tf.Tensor:
        return self.apply(self.params(), features)

    @staticmethod
    def apply(params: DenseParams, features: tf.Tensor) -> tf.Tensor:
        return tf.tensordot(features, params.W, 1) + params.b
