"""A run's encoder from its configuration, and what the engine asks of any encoder."""
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
