"""LSTM layers with DiPietro et al.'s cell: forget gate, peepholes, zero initial state, resets.

Cell, for each time step t (``*`` elementwise, ``sigma`` the logistic function)::

    g = tanh(x W_gx + h_{t-1} W_gh + b_g)
    i = sigma(x W_ix + h_{t-1} W_ih + w_ic * c_{t-1} + b_i)
    f = sigma(x W_fx + h_{t-1} W_fh + w_fc * c_{t-1} + b_f)
    c_t = g * i + c_{t-1} * f
    o = sigma(x W_ox + h_{t-1} W_oh + w_oc * c_t + b_o)
    h_t = o * tanh(c_t)

Where the reset flag of step t is set, ``(c_{t-1}, h_{t-1})`` is replaced by the zero initial state
before the step. The four gate matrices are stored fused, in gate order (g, i, f, o): ``W_x``
``[F, 4H]``, ``W_h`` ``[H, 4H]``, ``b`` ``[4H]``; peepholes ``w_ic, w_fc, w_oc`` ``[H]`` each. All weights
start uniform in ``[-init_scale, init_scale]``, biases at zero, as in the original code.

Shapes: batch-major ``[B, T, ...]`` at the API, time-major inside the scan.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import tensorflow as tf

ResetMode = Literal["original", "corrected"]
RESET_MODES = ("original", "corrected")


@dataclass(frozen=True)
class EncoderConfig:
    """Shape of the recurrent encoder."""

    hidden: int = 1024
    layers: int = 1
    bidirectional: bool = True
    keep_prob: float = 0.5          # dropout keep probability on each layer's inputs and outputs
    init_scale: float = 0.1
    reset_mode: ResetMode = "original"

    def __post_init__(self):
        if self.reset_mode not in RESET_MODES:
            raise ValueError(f"reset_mode must be one of {RESET_MODES}, not {self.reset_mode!r}")

    @property
    def output_size(self) -> int:
        return self.hidden * (2 if self.bidirectional else 1)


class LSTMCellWeights(tf.Module):
    """Trainable weights of one LSTM layer in one direction."""

    def __init__(self, input_size: int, hidden: int, init_scale: float, rng: tf.random.Generator,
                 name: str):
        super().__init__(name=name)

        def uniform(shape, var_name):
            return tf.Variable(rng.uniform(shape, -init_scale, init_scale), name=var_name)

        self.W_x = uniform([input_size, 4 * hidden], "W_x")
        self.W_h = uniform([hidden, 4 * hidden], "W_h")
        self.peep = uniform([3, hidden], "peepholes")   # rows: w_ic, w_fc, w_oc
        self.b = tf.Variable(tf.zeros([4 * hidden]), name="b")


def lstm_scan(x_proj: tf.Tensor, resets: tf.Tensor, W_h: tf.Variable, peep: tf.Variable
              ) -> tf.Tensor:
    """Run the cell over time.

    Args:
        x_proj: ``[T, B, 4H]`` time-major ``x W_x + b`` for every step (one product for all steps).
        resets: ``[T, B, 1]`` float32, 1.0 where the state restarts before the step.
        W_h: ``[H, 4H]`` recurrent weights; peep: ``[3, H]`` peepholes.

    Returns:
        ``[T, B, H]`` hidden outputs h_t.
    """
    batch = tf.shape(x_proj)[1]
    hidden = tf.shape(W_h)[0]
    zeros = tf.zeros(tf.stack([batch, hidden]))
    w_ic, w_fc, w_oc = peep[0], peep[1], peep[2]

    def step(state, inputs):
        c_prev, h_prev = state
        z_x, r = inputs
        keep = 1.0 - r
        c_prev, h_prev = c_prev * keep, h_prev * keep
        z = z_x + tf.matmul(h_prev, W_h)
        z_g, z_i, z_f, z_o = tf.split(z, 4, axis=1)
        g = tf.tanh(z_g)
        i = tf.sigmoid(z_i + w_ic * c_prev)
        f = tf.sigmoid(z_f + w_fc * c_prev)
        c = g * i + c_prev * f
        o = tf.sigmoid(z_o + w_oc * c)
        return c, o * tf.tanh(c)

    _, h = tf.scan(step, (x_proj, resets), initializer=(zeros, zeros))
    return h


def reverse_resets(resets: tf.Tensor, mode: ResetMode) -> tf.Tensor:
    """Reset flags for the reverse direction, in forward time order, ``[B, T]``.

    ``original`` reproduces DiPietro's code: the flags are reversed together with the inputs, so in
    reverse time the state restarts before each sequence's *first* frame (and carries over from the
    following wrapped copy into a sequence's last frame). ``corrected`` restarts the reverse state
    before each sequence's *last* frame: the flag of step t is the forward flag of step t + 1.
    """
    if mode == "original":
        return resets
    ones = tf.ones_like(resets[:, :1])
    return tf.concat([resets[:, 1:], ones], axis=1)


class RecurrentEncoder(tf.Module):
    """Stacked (bi)directional LSTM: ``[B, T, F]`` -> ``[B, T, H]`` or ``[B, T, 2H]`` (fw, rv)."""

    def __init__(self, input_size: int, config: EncoderConfig, rng: tf.random.Generator):
        super().__init__(name="encoder")
        self.config = config
        directions = ("fw", "rv") if config.bidirectional else ("fw",)
        self.cells = {
            d: [LSTMCellWeights(input_size if layer == 0 else config.hidden, config.hidden,
                                config.init_scale, rng, name=f"{d}_layer{layer}")
                for layer in range(config.layers)]
            for d in directions}

    def __call__(self, inputs: tf.Tensor, resets: tf.Tensor, dropout_rng: tf.random.Generator | None
                 ) -> tf.Tensor:
        """``inputs`` ``[B, T, F]`` float32, ``resets`` ``[B, T]`` bool; ``dropout_rng`` None = no dropout."""
        outputs = [self._direction(inputs, resets, "fw", dropout_rng)]
        if "rv" in self.cells:
            rv_resets = reverse_resets(resets, self.config.reset_mode)
            rv = self._direction(tf.reverse(inputs, [1]), tf.reverse(rv_resets, [1]), "rv",
                                 dropout_rng)
            outputs.append(tf.reverse(rv, [1]))
        return tf.concat(outputs, axis=2)

    def _direction(self, inputs, resets, direction, dropout_rng):
        """One direction's stack; each direction draws its own dropout masks, as in the original."""
        r = tf.transpose(tf.cast(resets, tf.float32))[:, :, None]
        x = dropout(tf.transpose(inputs, [1, 0, 2]), self.config.keep_prob, dropout_rng)
        for cell in self.cells[direction]:
            h = lstm_scan(tf.tensordot(x, cell.W_x, 1) + cell.b, r, cell.W_h, cell.peep)
            x = dropout(h, self.config.keep_prob, dropout_rng)
        return tf.transpose(x, [1, 0, 2])


def dropout(x: tf.Tensor, keep_prob: float, rng: tf.random.Generator | None) -> tf.Tensor:
    """Inverted dropout with an independent mask per element and time step (never across time)."""
    if rng is None or keep_prob >= 1.0:
        return x
    return tf.nn.experimental.stateless_dropout(x, rate=1.0 - keep_prob,
                                                seed=rng.make_seeds(1)[:, 0])
