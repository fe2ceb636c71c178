"""GradNorm (Chen et al. 2018) as van Amsterdam et al. state it, on the last shared layer.

Per training sweep, with task losses L_i and weights w_i:

* the network is updated with the gradient of ``sum_i w_i L_i`` (weights held constant);
* ``G_i = ||grad_W (w_i L_i)||_2`` on the shared weights ``W`` = every variable of the encoder's
  last layer, both directions (the BiLSTM layer the heads read; for a TCN its last layer the
  heads read, ``shared_layer_variables``), ``G_bar = mean_i G_i``;
* ``r_i = (L_i / L_i(0)) / mean_j (L_j / L_j(0))``, ``L_i(0)`` the losses of the first sweep
  (Chen et al.'s relative inverse training rate; ``relative_rate="paper"`` divides by the mean
  loss ``mean_j L_j`` instead, the paper's literal words, see docs/REPRODUCTION.md);
* ``L_grad = sum_i |G_i - G_bar * r_i^alpha|`` with the target held constant, and
  ``w <- w - lr_w * dL_grad/dw`` (plain SGD); since ``G_i = w_i ||grad_W L_i||``, the derivative is
  ``sign(G_i - target_i) * ||grad_W L_i||``, exact without second-order terms;
* then the weights are clipped positive and renormalised to sum to the number of tasks.

Two backward passes per sweep (one per task, ``per_task_gradients``) give both the per-task norms
and, by linearity, the weighted network gradient.
"""
from __future__ import annotations

import numpy as np
import tensorflow as tf

from rnn_seg.runs.folder import GRADNORM_LOG
from rnn_seg.trainer import Trainer, append_csv_row

from .config import RELATIVE_RATES, GradNormConfig, RelativeRate  # noqa: F401 (re-exported)

MIN_WEIGHT = 1e-3


def shared_layer_variables(model) -> list[tf.Variable]:
    """GradNorm's ``W``: the last layer both heads read (``SegmentationModel.shared_variables``:
    the LSTM's last layer of every direction, ED-TCN's last decoder layer, MS-TCN's last stage's
    last residual layer)."""
    return model.shared_variables()


class GradNormTrainer(Trainer):
    """``Trainer`` whose task weights follow GradNorm; logs ``gradnorm.csv`` at each progress line.

    Uses the four hooks of ``rnn_seg.trainer.Trainer`` (its docstring lists a sweep's calls in
    order): ``per_task_gradients`` (one gradient list per task), ``update`` (the network step
    with the current weights, then GradNorm's weight step), ``record`` (the losses, keeping
    G_i, r_i and w_i for the log), ``_on_log`` (gradnorm.csv), and ``extra_state`` checkpoints
    the weights and the first sweep's losses.
    """

    def __init__(self, *args, gradnorm: GradNormConfig, **kwargs):
        super().__init__(*args, **kwargs)
        self.gradnorm = gradnorm
        n = len(self.tasks)
        self.weights = tf.Variable(tf.ones([n]), trainable=False, name="task_weights")
        self.initial_losses = tf.Variable(tf.zeros([n]), trainable=False, name="initial_losses")
        self.shared = shared_layer_variables(self.model)
        self._stats: list[np.ndarray] = []

    def extra_state(self) -> dict:
        return {"task_weights": self.weights, "initial_losses": self.initial_losses}

    per_task_gradients = True

    def update(self, losses, grads, learning_rate):
        """``Trainer.update``: the network step with the current weights, then GradNorm's
        weight step (graph code).

        Args:
            losses: ``[n_tasks]`` float32 task losses L_i of the sweep.
            grads: one gradient list (in ``self.variables`` order) per task.
            learning_rate: scalar float32, the network's learning rate for the sweep.

        Returns:
            ``[4, n_tasks]`` float32: losses, G_i, r_i, and the weights used for this sweep.
        """
        weights = tf.identity(self.weights)
        network = [tf.add_n([weights[i] * g[k] for i, g in enumerate(grads)])
                   for k in range(len(self.variables))]
        self.sgd.apply(network, self.variables, learning_rate)

        shared_ids = {id(v) for v in self.shared}
        norms = tf.stack([tf.linalg.global_norm([g for g, v in zip(task_grads, self.variables)
                                                 if id(v) in shared_ids])
                          for task_grads in grads])                       # ||grad_W L_i||
        self.initial_losses.assign(tf.where(self.initial_losses > 0, self.initial_losses, losses))
        G = weights * norms
        ratio = losses / self.initial_losses
        r = ratio / tf.reduce_mean(ratio if self.gradnorm.relative_rate == "chen" else losses)
        target = tf.reduce_mean(G) * r ** self.gradnorm.alpha               # held constant
        d_weights = tf.sign(G - target) * norms                            # dL_grad / dw_i
        new = tf.maximum(weights - self.gradnorm.learning_rate * d_weights, MIN_WEIGHT)
        self.weights.assign(new * len(self.tasks) / tf.reduce_sum(new))
        return tf.stack([losses, G, r, weights])

    def record(self, out):
        self._stats.append(out[1:])
        return out[0]

    def _on_log(self, done: int) -> None:
        """Mean G_i, r_i and weights since the last progress line, one CSV row."""
        if not self._stats:
            return
        G, r, w = np.mean(self._stats, axis=0)
        row = {"sweep": done, "unit": round(done / self.sweeps_per_unit, 3)}
        for i, task in enumerate(self.tasks):
            row.update({f"w_{task.name}": w[i], f"G_{task.name}": G[i], f"r_{task.name}": r[i]})
        row.update({f"w_end_{t.name}": float(v) for t, v in zip(self.tasks, self.weights.numpy())})
        append_csv_row(self.run_dir / GRADNORM_LOG, row)
        self._stats = []
