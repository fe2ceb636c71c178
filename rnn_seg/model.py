"""A recurrent encoder shared by one fully connected head per task."""
from __future__ import annotations

from typing import Sequence, TypedDict

import tensorflow as tf

from .dense import Dense, DenseParams
from .lstm import EncoderConfig, EncoderParams, RecurrentEncoder
from .tasks import Task


class ModelParams(TypedDict):
    """Every weight of a ``SegmentationModel``; ``tf.nest`` flattens it in a fixed order."""

    encoder: EncoderParams
    heads: dict[str, DenseParams]


class SegmentationModel(tf.Module):
    """``inputs [B, T, F]`` -> ``{task name: outputs [B, T, K_task]}``.

    Weights are drawn from one generator seeded with ``seed``: the encoder's first, then each head
    in task order, so the same seed and tasks give the same initial model. ``apply`` runs the model
    with any weights of the same structure (``params()``), e.g. one slice of several models'
    stacked weights; ``infer(inputs, resets)`` is the compiled evaluation pass (no dropout).
    """

    def __init__(self, input_size: int, encoder: EncoderConfig, tasks: Sequence[Task], seed: int):
        super().__init__(name="segmentation_model")
        rng = tf.random.Generator.from_seed(seed)
        self.encoder = RecurrentEncoder(input_size, encoder, rng)
        self.heads = {t.name: Dense(encoder.output_size, t.num_outputs, encoder.init_scale, rng,
                                    name=f"head_{t.name}") for t in tasks}
        self.infer = tf.function(self._infer, input_signature=[
            tf.TensorSpec([None, None, input_size], tf.float32, name="inputs"),
            tf.TensorSpec([None, None], tf.bool, name="resets")])

    @property
    def dropout_calls(self) -> int:
        """Rows of the ``dropout_seeds`` a training call takes."""
        return self.encoder.dropout_calls

    def params(self) -> ModelParams:
        return {"encoder": self.encoder.params(),
                "heads": {name: head.params() for name, head in self.heads.items()}}

    def __call__(self, inputs: tf.Tensor, resets: tf.Tensor,
                 dropout_seeds: tf.Tensor | None = None) -> dict[str, tf.Tensor]:
        return self.apply(self.params(), inputs, resets, dropout_seeds)

    def _infer(self, inputs: tf.Tensor, resets: tf.Tensor) -> dict[str, tf.Tensor]:
        """``infer``: the model without dropout, as one graph traced once for every ``[B, T]``."""
        return self(inputs, resets, None)

    def initial_state(self, batch: int = 1) -> tf.Tensor:
        """Recurrent state before a sequence's first ``step`` (see ``RecurrentEncoder.step``)."""
        return self.encoder.initial_state(batch)

    def step(self, inputs: tf.Tensor, state: tf.Tensor) -> tuple[dict[str, tf.Tensor], tf.Tensor]:
        """One time step of a forward-only model without dropout: ``inputs`` ``[B, F]`` and the
        recurrent state -> ``({task name: outputs [B, K_task]}, state after the step)``."""
        params = self.params()
        features, state = self.encoder.step(params["encoder"], inputs, state)
        return {name: Dense.apply(params["heads"][name], features) for name in self.heads}, state

    def apply(self, params: ModelParams, inputs: tf.Tensor, resets: tf.Tensor,
              dropout_seeds: tf.Tensor | None = None, valid: tf.Tensor | None = None
              ) -> dict[str, tf.Tensor]:
        """The model with weights ``params`` (this model's own, or any of the same structure).

        Args:
            params: the encoder's and every head's weights (``params()``'s structure).
            inputs: ``[B, T, F]`` float32.
            resets: ``[B, T]`` bool, True where the state restarts before the step.
            dropout_seeds: ``[dropout_calls, 2]`` int64 stateless seeds, or None (evaluation: no
                dropout).
            valid: ``[B, T]`` bool for sweeps padded at the end (``RecurrentEncoder.apply``);
                None = all valid.

        Returns:
            ``{task name: raw outputs [B, T, K_task] float32}``.
        """
        features = self.encoder.apply(params["encoder"], inputs, resets, dropout_seeds, valid)
        return {name: Dense.apply(params["heads"][name], features) for name in self.heads}
