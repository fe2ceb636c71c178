"""A recurrent encoder shared by one fully connected head per task."""
from __future__ import annotations

from typing import Sequence

import tensorflow as tf

from .dense import Dense
from .lstm import EncoderConfig, RecurrentEncoder
from .tasks import Task


class SegmentationModel(tf.Module):
    """``inputs [B, T, F]`` -> ``{task name: outputs [B, T, K_task]}``.

    Weights are drawn from one generator seeded with ``seed``: the encoder's first, then each head
    in task order, so the same seed and tasks give the same initial model.
    """

    def __init__(self, input_size: int, encoder: EncoderConfig, tasks: Sequence[Task], seed: int):
        super().__init__(name="segmentation_model")
        rng = tf.random.Generator.from_seed(seed)
        self.encoder = RecurrentEncoder(input_size, encoder, rng)
        self.heads = {t.name: Dense(encoder.output_size, t.num_outputs, encoder.init_scale, rng,
                                    name=f"head_{t.name}") for t in tasks}

    def __call__(self, inputs: tf.Tensor, resets: tf.Tensor,
                 dropout_rng: tf.random.Generator | None = None) -> dict[str, tf.Tensor]:
        """``resets`` ``[B, T]`` bool; ``dropout_rng`` None (evaluation) disables dropout."""
        features = self.encoder(inputs, resets, dropout_rng)
        return {name: head(features) for name, head in self.heads.items()}
