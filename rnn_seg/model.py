"""An encoder shared by one fully connected head per task (and, for MS-TCN, refinement stages)."""
from __future__ import annotations

from typing import Sequence, TypedDict

import tensorflow as tf

from .config import EncoderConfig
from .dense import Dense, DenseParams
from .encoders.registry import PADDED, build_encoder, layout, shared_variables
from .encoders.config import AnyEncoderConfig, CustomEncoderConfig, MSTCNConfig
from .tasks import Task


class ModelParams(TypedDict, total=False):
    """Every weight of a ``SegmentationModel``; ``tf.nest`` flattens it in a fixed order.
    ``refinement`` only for an MS-TCN of more than one stage."""

    encoder: object
    heads: dict[str, DenseParams]
    refinement: list[dict]


class SegmentationModel(tf.Module):
    """``inputs [B, T, F]`` -> ``{task name: outputs [B, T, K_task]}``.

    Weights are drawn from one generator seeded with ``seed``: the encoder's first, then each head
    in task order (then an MS-TCN's refinement stages), so the same seed and tasks give the same
    initial model. ``apply`` runs the model with any weights of the same structure
    (``params()``), e.g. one slice of several models' stacked weights; ``losses`` is the training
    objective per task; ``infer(inputs, resets)`` is the compiled evaluation pass (no dropout).
    ``padded``: the encoder takes sweeps padded at the end rather than wrapped
    (``rnn_seg.encoders``).
    """

    def __init__(self, input_size: int, encoder: AnyEncoderConfig, tasks: Sequence[Task],
                 seed: int):
        super().__init__(name="segmentation_model")
        rng = tf.random.Generator.from_seed(seed)
        self.encoder = build_encoder(input_size, encoder, rng)
        self.padded = layout(self.encoder) == PADDED
        width = (self.encoder.output_size if isinstance(encoder, CustomEncoderConfig)
                 else encoder.output_size)          # a user's: its layer's, once built
        glorot = getattr(encoder, "head_init", None) == "glorot"
        self.heads = {t.name: Dense(width, t.num_outputs, _head_scale(encoder, width,
                                                                      t.num_outputs), rng,
                                    name=f"head_{t.name}", zero_bias=glorot) for t in tasks}
        self._multistage = isinstance(encoder, MSTCNConfig)
        if self._multistage and encoder.stages > 1:
            from .encoders.ms_tcn import Refinement
            self.refinement = Refinement(tasks, encoder, rng)
        # Traced without AutoGraph, as every graph function of the engine: its graph code never
        # branches or loops on a tensor in Python (its loops are tf.while_loop), and AutoGraph
        # does not convert Keras's code, so a user's layer is traced as written either way; its
        # conversion cost seconds in every process that trains or predicts and added no op.
        self.infer = tf.function(self._infer, autograph=False, input_signature=[
            tf.TensorSpec([None, None, input_size], tf.float32, name="inputs"),
            tf.TensorSpec([None, None], tf.bool, name="resets")])

    @property
    def dropout_calls(self) -> int:
        """Rows of the ``dropout_seeds`` a training call takes."""
        extra = self.refinement.dropout_calls if hasattr(self, "refinement") else 0
        return self.encoder.dropout_calls + extra

    def params(self) -> ModelParams:
        params = {"encoder": self.encoder.params(),
                  "heads": {name: head.params() for name, head in self.heads.items()}}
        if hasattr(self, "refinement"):
            params["refinement"] = self.refinement.params()
        return params

    def shared_variables(self) -> list[tf.Variable]:
        """The last layer every head reads: GradNorm's ``W`` (``rnn_seg.encoders``)."""
        if hasattr(self, "refinement"):
            return self.refinement.shared_variables()
        return shared_variables(self.encoder)

    def __call__(self, inputs: tf.Tensor, resets: tf.Tensor,
                 dropout_seeds: tf.Tensor | None = None) -> dict[str, tf.Tensor]:
        return self.apply(self.params(), inputs, resets, dropout_seeds)

    def _infer(self, inputs: tf.Tensor, resets: tf.Tensor) -> dict[str, tf.Tensor]:
        """``infer``: the model without dropout, as one graph traced once for every ``[B, T]``."""
        return self(inputs, resets, None)

    def initial_state(self, batch: int = 1) -> tf.Tensor:
        """Recurrent state before a sequence's first ``step`` (see ``RecurrentEncoder.step``)."""
        self._require_recurrent()
        return self.encoder.initial_state(batch)

    def step(self, inputs: tf.Tensor, state: tf.Tensor) -> tuple[dict[str, tf.Tensor], tf.Tensor]:
        """One time step of a forward-only model without dropout: ``inputs`` ``[B, F]`` and the
        recurrent state -> ``({task name: outputs [B, K_task]}, state after the step)``."""
        self._require_recurrent()
        params = self.params()
        features, state = self.encoder.step(params["encoder"], inputs, state)
        return {name: Dense.apply(params["heads"][name], features) for name in self.heads}, state

    def _require_recurrent(self) -> None:
        if self.padded:
            raise ValueError(f"only an LSTM encoder runs one sample at a time; this model's is "
                             f"{self.encoder.config.kind}: predict whole recordings (without "
                             "--stream; a causal TCN's output at a sample reads only the past)")

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
            ``{task name: raw outputs [B, T, K_task] float32}`` (an MS-TCN's last stage's).
        """
        return self.stage_outputs(params, inputs, resets, dropout_seeds, valid)[-1]

    def stage_outputs(self, params: ModelParams, inputs: tf.Tensor, resets: tf.Tensor,
                      dropout_seeds: tf.Tensor | None = None, valid: tf.Tensor | None = None
                      ) -> list[dict[str, tf.Tensor]]:
        """Every stage's outputs, first to last (one stage but for an MS-TCN); arguments as
        ``apply``'s."""
        calls = self.encoder.dropout_calls
        seeds = None if dropout_seeds is None else dropout_seeds[:calls]
        features = self.encoder.apply(params["encoder"], inputs, resets, seeds, valid)
        outputs = {name: Dense.apply(params["heads"][name], features) for name in self.heads}
        if not self._multistage:
            return [outputs]
        from .encoders.convolution import mask_of
        mask = mask_of(valid, inputs)
        outputs = {name: value * mask for name, value in outputs.items()}
        if "refinement" not in params:
            return [outputs]
        later = None if dropout_seeds is None else dropout_seeds[calls:]
        return [outputs, *self.refinement.apply(params["refinement"], outputs, mask, later)]

    def losses(self, params: ModelParams, tasks: Sequence[Task], inputs: tf.Tensor,
               resets: tf.Tensor, targets: Sequence[tf.Tensor],
               dropout_seeds: tf.Tensor | None = None, valid: tf.Tensor | None = None
               ) -> tf.Tensor:
        """The training objective per task, ``[n_tasks]`` float32: each task's loss
        (``Task.loss``) on the outputs; for an MS-TCN summed over its stages, each with the
        smoothing term (``rnn_seg.encoders.ms_tcn.stage_loss``). ``targets``: one
        ``[B, T, K_task]`` array per task of ``tasks``; the rest as ``apply``'s arguments."""
        stages = self.stage_outputs(params, inputs, resets, dropout_seeds, valid)
        if not self._multistage:
            outputs = stages[-1]
            return tf.stack([t.loss(outputs[t.name], y, valid) for t, y in zip(tasks, targets)])
        from .encoders.ms_tcn import stage_loss
        config = self.encoder.config
        return tf.add_n([tf.stack([stage_loss(t, outputs[t.name], y, valid, config)
                                   for t, y in zip(tasks, targets)]) for outputs in stages])


def _head_scale(encoder: AnyEncoderConfig, width: int, outputs: int) -> float:
    """The initial weights' bound of a head of ``outputs`` outputs on ``width`` features: the
    LSTM's ``init_scale`` (DiPietro's uniform), another encoder's ``1 / sqrt(width)`` (PyTorch's
    default for a 1x1 convolution, MS-TCN's heads), or Glorot's ``sqrt(6 / (width + outputs))``
    for an ED-TCN with ``head_init = "glorot"`` (Keras's ``Dense``, Lea et al.'s)."""
    if isinstance(encoder, EncoderConfig):
        return encoder.init_scale
    if getattr(encoder, "head_init", None) == "glorot":
        return (6.0 / (width + outputs)) ** 0.5
    return 1.0 / width ** 0.5
