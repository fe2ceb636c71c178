"""A run's encoder from its configuration, and what the engine asks of any encoder."""
from __future__ import annotations

import tensorflow as tf

from .config import AnyEncoderConfig, CustomEncoderConfig, EDTCNConfig, MSTCNConfig

#: How an encoder's sweeps are laid out (``rnn_seg.trainer.Trainer.batch``).
WRAPPED, PADDED = "wrapped", "padded"


def build_encoder(input_size: int, config: AnyEncoderConfig, rng: tf.random.Generator
                  ) -> tf.Module:
    """The encoder ``config`` describes, its weights drawn from ``rng`` (a user's encoder: its
    module imported and its layer built, ``keras_layer``)."""
    if isinstance(config, CustomEncoderConfig):
        from .keras_layer import KerasEncoder
        return KerasEncoder(input_size, config, rng)
    if isinstance(config, EDTCNConfig):
        from .ed_tcn import EDTCNEncoder
        return EDTCNEncoder(input_size, config, rng)
    if isinstance(config, MSTCNConfig):
        from .ms_tcn import MSTCNEncoder
        return MSTCNEncoder(input_size, config, rng)
    from ..lstm import RecurrentEncoder
    return RecurrentEncoder(input_size, config, rng)


def layout(encoder: tf.Module) -> str:
    """``WRAPPED`` (the LSTM) or ``PADDED`` (the convolutional encoders, a user's own)."""
    return getattr(encoder, "layout", WRAPPED)


def shared_variables(encoder: tf.Module) -> list[tf.Variable]:
    """The encoder's last layer, which the heads read: GradNorm's ``W`` (the LSTM's last layer
    of every direction)."""
    if layout(encoder) == WRAPPED:
        return [v for cells in encoder.cells.values() for v in cells[-1].trainable_variables]
    return encoder.shared_variables()


def resume_on(encoder: tf.Module, started: str | None) -> None:
    """Let a resumed run's ``encoder`` run the loops its run started on (``started``: config.json's
    ``provenance.loops``; None in older records, which keep the asked loops): the LSTM's
    ``RecurrentEncoder.resume_on``; the convolutional encoders have no loops to choose."""
    method = getattr(encoder, "resume_on", None)
    if method is not None and started is not None:
        method(started)
