"""Farha & Gall's multi-stage temporal convolutional network (MS-TCN, CVPR 2019), multi-task.

One stage, for ``layers`` L, ``filters`` F, kernel k and dropout p (``MSTCNConfig``)::

    x = conv_1(x) * valid                                          F maps
    for l = 0..L-1:   x = (x + drop_p(conv_1(relu(conv_k,2^l(x))))) * valid
    outputs = {task: Dense_task(x) * valid}                        one head per task

``conv_k,d`` a temporal convolution of k taps d steps apart (``convolution.conv``; causal when
online), ``conv_1`` a 1x1 convolution. Stage 1 reads the inputs and is the ``MSTCNEncoder`` (its
heads are the model's own, ``rnn_seg.model``); each later stage (``Refinement``) reads the
previous stage's predictions of *every* head, ``task.scores_tf`` (probabilities; a regression's
value) side by side, and has heads of its own. So the progress head sits at every stage, like
the gesture head, and each stage refines both tasks from both: the multi-task reading of "each
stage refines the previous one's predictions" (docs/REPRODUCTION.md). The model's outputs are the
last stage's; training sums every stage's losses, each task's loss in a stage being its own loss
plus ``smoothing_weight`` times ``smoothing`` of its log-probabilities (gestures, progress
classification and ordered classification; a regression head has none). GradNorm's shared layer
is the last stage's last residual layer, which both last heads read.
"""
from __future__ import annotations

from typing import Sequence

import tensorflow as tf

from ..dense import Dense, DenseParams
from ..tasks import Task, step_mean
from .config import MSTCNConfig
from .convolution import Conv, conv, dropout, mask_of

#: A stage's weights: "input" ConvParams, "dilated" and "pointwise" one ConvParams per layer.
StageParams = dict[str, object]


class DilatedStage(tf.Module):
    """A stage's trunk: ``[B, T, C_in]`` -> ``[B, T, filters]`` (module docstring)."""

    def __init__(self, input_size: int, config: MSTCNConfig, rng: tf.random.Generator,
                 name: str):
        super().__init__(name=name)
        self.config = config
        F = config.filters
        self.input = Conv(1, input_size, F, rng, "torch", name="input")
        self.dilated = [Conv(config.kernel, F, F, rng, "torch", name=f"dilated{l}")
                        for l in range(config.layers)]
        self.pointwise = [Conv(1, F, F, rng, "torch", name=f"pointwise{l}")
                          for l in range(config.layers)]

    def params(self) -> StageParams:
        return {"input": self.input.params(), "dilated": [c.params() for c in self.dilated],
                "pointwise": [c.params() for c in self.pointwise]}

    def last_layer_variables(self) -> list[tf.Variable]:
        """The last residual layer's weights (GradNorm's shared layer of the last stage)."""
        return [*self.dilated[-1].trainable_variables, *self.pointwise[-1].trainable_variables]

    def apply(self, params: StageParams, x: tf.Tensor, mask: tf.Tensor,
              dropout_seeds: tf.Tensor | None) -> tf.Tensor:
        """``x`` ``[B, T, C_in]``, ``mask`` ``[B, T, 1]`` float32, ``dropout_seeds`` one row per
        layer (None = no dropout) -> ``[B, T, filters]``."""
        x = conv(x, params["input"]) * mask
        for l, (dilated, pointwise) in enumerate(zip(params["dilated"], params["pointwise"])):
            branch = tf.nn.relu(conv(x, dilated, 2 ** l, self.config.causal))
            branch = conv(branch, pointwise)
            seed = None if dropout_seeds is None else dropout_seeds[l]
            x = (x + dropout(branch, self.config.dropout, seed)) * mask
        return x


class MSTCNEncoder(tf.Module):
    """Stage 1's trunk: ``[B, T, F_in]`` -> ``[B, T, filters]``; the model's heads read it."""

    layout = "padded"    # one sequence per row, zeros after its end (rnn_seg.encoders)

    def __init__(self, input_size: int, config: MSTCNConfig, rng: tf.random.Generator):
        super().__init__(name="encoder")
        self.config = config
        self.stage = DilatedStage(input_size, config, rng, name="stage1")

    @property
    def dropout_calls(self) -> int:
        return self.config.layers

    def params(self) -> StageParams:
        return self.stage.params()

    def shared_variables(self) -> list[tf.Variable]:
        """GradNorm's ``W`` when there is one stage: its last residual layer."""
        return self.stage.last_layer_variables()

    def apply(self, params: StageParams, inputs: tf.Tensor, resets: tf.Tensor,
              dropout_seeds: tf.Tensor | None, valid: tf.Tensor | None = None) -> tf.Tensor:
        """As ``EDTCNEncoder.apply``: ``[B, T, F_in]`` -> ``[B, T, filters]``, zero where not
        ``valid``; ``resets`` unused."""
        del resets
        mask = mask_of(valid, inputs)
        return self.stage.apply(params, inputs * mask, mask, dropout_seeds)


class Refinement(tf.Module):
    """Stages 2..S: each reads the previous stage's scores of every task (module docstring)."""

    def __init__(self, tasks: Sequence[Task], config: MSTCNConfig, rng: tf.random.Generator):
        super().__init__(name="refinement")
        self.config = config
        self.tasks = tuple(tasks)
        scores = sum(t.num_outputs for t in tasks)
        self.stages = [DilatedStage(scores, config, rng, name=f"stage{s + 2}")
                       for s in range(config.stages - 1)]
        self.heads = [{t.name: Dense(config.filters, t.num_outputs, config.filters ** -0.5, rng,
                                     name=f"stage{s + 2}_head_{t.name}") for t in tasks}
                      for s in range(config.stages - 1)]

    @property
    def dropout_calls(self) -> int:
        return len(self.stages) * self.config.layers

    def params(self) -> list[dict]:
        return [{"trunk": stage.params(),
                 "heads": {name: head.params() for name, head in heads.items()}}
                for stage, heads in zip(self.stages, self.heads)]

    def shared_variables(self) -> list[tf.Variable]:
        """GradNorm's ``W``: the last stage's last residual layer."""
        return self.stages[-1].last_layer_variables()

    def apply(self, params: list[dict], outputs: dict[str, tf.Tensor], mask: tf.Tensor,
              dropout_seeds: tf.Tensor | None) -> list[dict[str, tf.Tensor]]:
        """Stage 1's ``outputs`` ``{task: [B, T, K]}`` -> each later stage's, in order."""
        stages = []
        for s, stage in enumerate(params):
            scores = tf.concat([t.scores_tf(outputs[t.name]) for t in self.tasks], axis=2) * mask
            layers = self.config.layers
            seeds = None if dropout_seeds is None else dropout_seeds[s * layers:(s + 1) * layers]
            x = self.stages[s].apply(stage["trunk"], scores, mask, seeds)
            outputs = {name: heads_apply(p, x, mask) for name, p in stage["heads"].items()}
            stages.append(outputs)
        return stages


def heads_apply(params: DenseParams, features: tf.Tensor, mask: tf.Tensor) -> tf.Tensor:
    """A head on ``[B, T, D]`` features, zero where not valid (as the reference's outputs)."""
    return Dense.apply(params, features) * mask


def smoothing(log_scores: tf.Tensor, valid: tf.Tensor | None, tau: float) -> tf.Tensor:
    """Farha & Gall's truncated MSE: the mean over neighbouring valid steps and outputs of
    ``min((log p_t - log p_{t-1})^2, tau^2)``, the earlier step held constant.

    Args:
        log_scores: ``[B, T, K]`` float32 log-probabilities (``Task.log_scores_tf``).
        valid: ``[B, T]`` bool, the real steps; None = all.
        tau: the truncation, in log-probability.

    Returns:
        Scalar float32.
    """
    change = log_scores[:, 1:] - tf.stop_gradient(log_scores[:, :-1])
    squared = tf.minimum(tf.square(change), tau * tau)
    pairs = None if valid is None else valid[:, 1:] & valid[:, :-1]
    return step_mean(squared, pairs)


def stage_loss(task: Task, outputs: tf.Tensor, targets: tf.Tensor, valid: tf.Tensor | None,
               config: MSTCNConfig) -> tf.Tensor:
    """One task's loss in one stage: its own plus the weighted smoothing of its log-scores."""
    loss = task.loss(outputs, targets, valid)
    log_scores = task.log_scores_tf(outputs)
    if log_scores is None or not config.smoothing_weight:
        return loss
    return loss + config.smoothing_weight * smoothing(log_scores, valid, config.smoothing_tau)
