"""Peers of ``rnn_seg``'s layer for ``lstm_sweep.py``: the same training sweep written with
PyTorch's ``nn.LSTM`` and with Keras's ``Bidirectional(LSTM)`` in our TensorFlow, as their users
would.

The workload is model A's sweep as ``lstm_sweep.py`` times it: inputs ``[B, T, F]`` float32,
inverted dropout 0.5 on the LSTM's inputs and outputs (a fresh mask per element and step), a
bidirectional LSTM of ``H`` units, a dense head ``2H -> K``, the mean softmax cross-entropy over
all steps against one-hot targets ``[B, T, K]``, gradients clipped to a global norm of 1 and one
SGD step (learning rate 1, no momentum); weights uniform in [-0.1, 0.1], biases as each library
starts them. What differs from ``rnn_seg`` and the per-gate reference, all of it cheap next to
the recurrent products:

- **No peepholes**: neither ``nn.LSTM`` nor Keras's cell has them, so each step lacks three
  ``[B, H]`` multiply-adds and their gradients.
- One input dropout mask for both directions (each library's bidirectional layer takes one
  input); ``rnn_seg`` draws one per direction.
- No reset flags: the benchmark's only reset is at step 0, which is the zero initial state the
  peers start from anyway.

bf16 runs the peer as its users would: PyTorch under ``torch.autocast("cpu", torch.bfloat16)``
(float32 weights, the LSTM's and the head's products in bfloat16), Keras under the
``mixed_bfloat16`` policy (float32 variables, layers compute in bfloat16). The loss, clipping
and update stay float32 in both, as in ``rnn_seg``'s bf16.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

INIT_SCALE = 0.1
DROPOUT = 0.5
LEARNING_RATE = 1.0
CLIP_NORM = 1.0


class Unsupported(Exception):
    """This peer cannot run the asked variant on this installation (the message says why)."""


def torch_step(hidden: int, precision: str, x: np.ndarray, y: np.ndarray,
               threads: tuple[int, int]) -> Callable[[], float]:
    """One PyTorch training sweep as a call.

    Args:
        hidden: units ``H`` per direction.
        precision: ``"fp32"``, or ``"bf16"`` for CPU autocast to bfloat16.
        x: ``[B, T, F]`` float32 inputs.
        y: ``[B, T, K]`` float32 one-hot targets.
        threads: (intra-op, inter-op) threads; set before any other PyTorch work.

    Returns:
        A call that runs one sweep (forward, backward, clipping, SGD step) and returns its loss.
    """
    import torch
    from torch import nn
    from torch.nn import functional

    torch.set_num_threads(threads[0])
    torch.set_num_interop_threads(threads[1])
    torch.manual_seed(0)
    lstm = nn.LSTM(x.shape[2], hidden, batch_first=True, bidirectional=True)
    head = nn.Linear(2 * hidden, y.shape[2])
    parameters = [*lstm.parameters(), *head.parameters()]
    for weight in (*lstm.parameters(), head.weight):
        nn.init.uniform_(weight, -INIT_SCALE, INIT_SCALE)
    sgd = torch.optim.SGD(parameters, lr=LEARNING_RATE, momentum=0.0)
    inputs, targets = torch.from_numpy(x), torch.from_numpy(y)
    autocast = torch.autocast("cpu", dtype=torch.bfloat16, enabled=precision == "bf16")
    if precision == "bf16":
        _require_bf16_lstm(lstm, inputs, autocast)

    def sweep() -> float:
        sgd.zero_grad(set_to_none=True)
        with autocast:
            features, _ = lstm(functional.dropout(inputs, DROPOUT))
            logits = head(functional.dropout(features, DROPOUT))
        loss = functional.cross_entropy(logits.float().flatten(0, 1), targets.flatten(0, 1))
        loss.backward()
        nn.utils.clip_grad_norm_(parameters, CLIP_NORM)
        sgd.step()
        return loss.item()
    return sweep


def _require_bf16_lstm(lstm, inputs, autocast) -> None:
    """Raise ``Unsupported`` unless ``lstm`` computes in bfloat16 under ``autocast``."""
    import torch

    with torch.no_grad(), autocast:
        dtype = lstm(inputs[:, :2])[0].dtype
    if dtype != torch.bfloat16:
        raise Unsupported(f"CPU autocast leaves nn.LSTM in {dtype} in this PyTorch")


def keras_step(hidden: int, precision: str, x: np.ndarray, y: np.ndarray) -> Callable[[], float]:
    """One Keras training sweep as a call, in this process's TensorFlow (threads set already).

    Args:
        hidden: units ``H`` per direction.
        precision: ``"fp32"``, or ``"bf16"`` for the ``mixed_bfloat16`` policy.
        x: ``[B, T, F]`` float32 inputs.
        y: ``[B, T, K]`` float32 one-hot targets.

    Returns:
        A call that runs one sweep (forward, backward, clipping, SGD step) and returns its loss.
    """
    import keras
    from jigsaws_tools.cli.common import import_tensorflow
    tf = import_tensorflow()

    keras.mixed_precision.set_global_policy("mixed_bfloat16" if precision == "bf16"
                                            else "float32")
    keras.utils.set_random_seed(0)
    init = keras.initializers.RandomUniform(-INIT_SCALE, INIT_SCALE)
    model = keras.Sequential([
        keras.Input(x.shape[1:]),
        keras.layers.Dropout(DROPOUT),
        keras.layers.Bidirectional(keras.layers.LSTM(
            hidden, return_sequences=True, kernel_initializer=init, recurrent_initializer=init)),
        keras.layers.Dropout(DROPOUT),
        keras.layers.Dense(y.shape[2], kernel_initializer=init),
    ])
    sgd = keras.optimizers.SGD(learning_rate=LEARNING_RATE, global_clipnorm=CLIP_NORM)
    sgd.build(model.trainable_variables)
    inputs, targets = tf.constant(x), tf.constant(y)

    @tf.function
    def step() -> tf.Tensor:
        with tf.GradientTape() as tape:
            logits = tf.cast(model(inputs, training=True), tf.float32)
            loss = tf.reduce_mean(tf.nn.softmax_cross_entropy_with_logits(targets, logits))
        sgd.apply(tape.gradient(loss, model.trainable_variables), model.trainable_variables)
        return loss
    return lambda: float(step())
