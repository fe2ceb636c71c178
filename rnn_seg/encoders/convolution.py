"""Temporal convolutions over ``[B, T, C]`` sequences padded at the end, and their helpers.

A sweep for a convolutional encoder holds one sequence per row from its first step, zeros after
its end (``valid`` ``[B, T]`` marks the real steps; ``rnn_seg.trainer``). Every layer multiplies
its output by ``valid``, so a sequence's outputs do not depend on how far its row is padded: the
same as the sequence alone (tested). A convolution pads with zeros: centred (non-causal, the
references' ``same`` padding, the extra tap of an even kernel on the future side) or entirely on
the past side (causal: the output at step t reads steps <= t only).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import tensorflow as tf


class ConvParams(NamedTuple):
    """Weights of one temporal convolution, as variables or (stacked) tensors."""

    W: tf.Tensor        # [kernel, C_in, C_out]
    b: tf.Tensor        # [C_out]


class Conv(tf.Module):
    """A temporal convolution's weights, uniform in ``[-s, s]``: ``s = sqrt(6 / (fan_in +
    fan_out))`` (Glorot, Keras's default: ED-TCN) or ``1 / sqrt(fan_in)`` (PyTorch's default:
    MS-TCN), ``fan = kernel * channels``; biases zero (Keras) or uniform alike (PyTorch)."""

    def __init__(self, kernel: int, inputs: int, outputs: int, rng: tf.random.Generator,
                 init: str, name: str):
        super().__init__(name=name)
        fan_in, fan_out = kernel * inputs, kernel * outputs
        if init == "glorot":
            scale = math.sqrt(6.0 / (fan_in + fan_out))
            bias = tf.zeros([outputs])
        else:
            scale = 1.0 / math.sqrt(fan_in)
            bias = rng.uniform([outputs], -scale, scale)
        self.W = tf.Variable(rng.uniform([kernel, inputs, outputs], -scale, scale), name="W")
        self.b = tf.Variable(bias, name="b")

    def params(self) -> ConvParams:
        return ConvParams(self.W, self.b)


def conv(x: tf.Tensor, params: ConvParams, dilation: int = 1, causal: bool = False) -> tf.Tensor:
    """``[B, T, C_in]`` -> ``[B, T, C_out]``: the convolution with zero padding (module
    docstring), taps ``dilation`` steps apart."""
    kernel = params.W.shape[0]
    span = dilation * (kernel - 1)
    past = span if causal else span // 2
    padded = tf.pad(x, [[0, 0], [past, span - past], [0, 0]])
    return tf.nn.convolution(padded, params.W, padding="VALID", dilations=[dilation]) + params.b


def mask_of(valid: tf.Tensor | None, like: tf.Tensor) -> tf.Tensor:
    """``[B, T, 1]`` float32 of ``valid`` ``[B, T]`` bool, or ones for None (every step real)."""
    if valid is None:
        return tf.ones_like(like[:, :, :1])
    return tf.cast(valid, tf.float32)[:, :, None]


def channel_normalise(x: tf.Tensor) -> tf.Tensor:
    """Lea et al.'s normalised ReLU's second half: each step's activations divided by their
    largest magnitude (+ 1e-5), ``[B, T, C]`` -> ``[B, T, C]``."""
    return x / (tf.reduce_max(tf.abs(x), axis=2, keepdims=True) + 1e-5)


def dropout(x: tf.Tensor, rate: float, seed: tf.Tensor | None, spatial: bool = False
            ) -> tf.Tensor:
    """Inverted dropout of ``[B, T, C]`` at ``rate``: elementwise, or ``spatial`` (one mask per
    sequence and channel, whole channels dropped, Keras's ``SpatialDropout1D``); ``seed``
    ``[2]`` int64 stateless seed, None = no dropout. Elementwise masks are drawn in time-major
    order, so a sweep padded at the end keeps every valid step's mask (``rnn_seg.stack``)."""
    if seed is None or rate <= 0.0:
        return x
    if spatial:
        shape = tf.shape(x)
        return tf.nn.experimental.stateless_dropout(
            x, rate=rate, seed=seed, noise_shape=tf.stack([shape[0], 1, shape[2]]))
    time_major = tf.transpose(x, [1, 0, 2])
    dropped = tf.nn.experimental.stateless_dropout(time_major, rate=rate, seed=seed)
    return tf.transpose(dropped, [1, 0, 2])


def pad_to_multiple(x: tf.Tensor, multiple: int, value: float = 0.0) -> tf.Tensor:
    """``[B, T, C]`` padded at the end with ``value`` (zeros by default) to a multiple of
    ``multiple`` steps."""
    steps = tf.shape(x)[1]
    extra = (multiple - steps % multiple) % multiple
    return tf.pad(x, [[0, 0], [0, extra], [0, 0]], constant_values=value)


def max_pool(x: tf.Tensor) -> tf.Tensor:
    """``[B, 2T, C]`` -> ``[B, T, C]``: the larger of each pair of steps."""
    return tf.nn.max_pool1d(x, ksize=2, strides=2, padding="VALID")


def upsample(x: tf.Tensor, causal: bool = False) -> tf.Tensor:
    """``[B, T, C]`` -> ``[B, 2T, C]``: each step twice. ``causal``: shifted one step later, so
    step ``t`` gets the pooled pair that ended at or before it (pair ``(t - 1) // 2``; zeros at
    the first step), and pooling leaks no future step into an online model."""
    repeated = tf.repeat(x, 2, axis=1)
    if not causal:
        return repeated
    return tf.concat([tf.zeros_like(repeated[:, :1]), repeated[:, :-1]], axis=1)
