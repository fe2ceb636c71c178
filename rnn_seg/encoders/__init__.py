"""Encoders: what turns a sweep of kinematic inputs into the features every head reads.

An encoder maps ``inputs [B, T, F]`` (with ``resets [B, T]`` and, for sweeps padded at the end,
``valid [B, T]``) to ``features [B, T, D]``, through ``apply(params, inputs, resets,
dropout_seeds, valid)`` with any weights of its ``params()`` structure; ``dropout_calls`` says how
many stateless seeds a training call takes. A run's configuration chooses one by its ``kind``
(``--encoder``, a grid spec's ``encoder``; ``rnn_seg.encoders.config``):

* ``lstm``: DiPietro et al.'s peephole (Bi)LSTM with its hand-written backward pass
  (``rnn_seg.lstm.RecurrentEncoder``, configured by ``rnn_seg.config.EncoderConfig``). Its sweeps
  are *wrapped*: shorter sequences repeated to the longest, the state reset at each copy;
* ``ed-tcn``: Lea et al.'s encoder-decoder TCN (``ed_tcn``);
* ``ms-tcn``: Farha & Gall's multi-stage TCN (``ms_tcn``), whose later stages refine every
  head's predictions (``ms_tcn.Refinement``, built by ``rnn_seg.model``).

The convolutional encoders take *padded* sweeps (``layout = "padded"``): one sequence per row,
zeros after its end, ``valid`` marking its steps (``convolution``). Online (``bidirectional``
False) means a forward LSTM or causal convolutions: the features at step t read steps <= t.

Modules: ``config`` (the TCNs' configurations and reference schedules; no TensorFlow),
``convolution`` (temporal convolutions and their helpers), ``ed_tcn``, ``ms_tcn``.
"""
from __future__ import annotations

import tensorflow as tf

from ..config import EncoderConfig
from .config import EDTCNConfig, MSTCNConfig

#: How an encoder's sweeps are laid out (``rnn_seg.trainer.Trainer.batch``).
WRAPPED, PADDED = "wrapped", "padded"


def build_encoder(input_size: int, config: EncoderConfig | EDTCNConfig | MSTCNConfig,
                  rng: tf.random.Generator) -> tf.Module:
    """The encoder ``config`` describes, its weights drawn from ``rng``."""
    if isinstance(config, EDTCNConfig):
        from .ed_tcn import EDTCNEncoder
        return EDTCNEncoder(input_size, config, rng)
    if isinstance(config, MSTCNConfig):
        from .ms_tcn import MSTCNEncoder
        return MSTCNEncoder(input_size, config, rng)
    from ..lstm import RecurrentEncoder
    return RecurrentEncoder(input_size, config, rng)


def layout(encoder: tf.Module) -> str:
    """``WRAPPED`` (the LSTM) or ``PADDED`` (the convolutional encoders)."""
    return getattr(encoder, "layout", WRAPPED)


def shared_variables(encoder: tf.Module) -> list[tf.Variable]:
    """The encoder's last layer, which the heads read: GradNorm's ``W`` (the LSTM's last layer
    of every direction)."""
    if layout(encoder) == WRAPPED:
        return [v for cells in encoder.cells.values() for v in cells[-1].trainable_variables]
    return encoder.shared_variables()
