"""The fused loops with ``rnn_seg.lstm``'s loop signatures (``_forward_loop``, ``_backward_loop``),
and the recurrent weights' gradient they sum with their own product (``rnn_seg.lstm``'s
``fused_weight_gradient`` says where).

The loops take the recurrent weights ``W`` ``[H, 4H]`` already in the products' dtype (float32, or
bfloat16 for ``bf16`` precision) and run the first ``steps`` of time-major inputs; later steps are
zeros, as the graph loops leave them.
"""
from __future__ import annotations

import tensorflow as tf

from .build import library


def forward_loop(x_proj: tf.Tensor, keep: tf.Tensor, W: tf.Tensor, peep: tf.Tensor,
                 steps: tf.Tensor) -> list[tf.Tensor]:
    """The cell over time: ``x_proj`` ``[T, B, 4H]`` (``x W_x + b``), ``keep`` ``[T, B, 1]``
    (0.0 where the state restarts before the step), ``peep`` ``[3, H]`` -> ``(h, c, g, i, f, o)``,
    each ``[T, B, H]`` float32."""
    return list(library().mtrnn_lstm_forward(x_proj, keep, W, peep, steps))


def backward_loop(dh_out: tf.Tensor, keep: tf.Tensor, state: list[tf.Tensor], c_prev: tf.Tensor,
                  W: tf.Tensor, peep: tf.Tensor, steps: tf.Tensor) -> tf.Tensor:
    """``dz`` ``[T, B, 4H]``, the gradient of the gate inputs, from the gradient ``dh_out``
    ``[T, B, H]`` at the outputs, the forward loop's ``state`` ``(h, c, g, i, f, o)`` and
    ``c_prev`` ``[T, B, H]``, the cell state entering each step (after its reset)."""
    _, c, g, i, f, o = state
    return library().mtrnn_lstm_backward(dh_out, keep, c, g, i, f, o, c_prev, W, peep, steps)


def weight_gradient(h_prev: tf.Tensor, dz: tf.Tensor) -> tf.Tensor:
    """``h_prev^T dz``, float32: ``h_prev`` ``[N, H]``, ``dz`` ``[N, 4H]`` -> ``[H, 4H]``, each
    element summed over blocks of 256 rows in order, the blocks' sums added in order (the same
    bits on any number of threads)."""
    return library().mtrnn_weight_gradient(h_prev, dz)
