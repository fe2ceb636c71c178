"""The original code's LSTM structure, for timing only: eight separate products per step in tf.scan.

Same cell and semantics as ``rnn_seg.lstm`` (peepholes, resets), written per gate as DiPietro et
al.'s ``_lstm_block`` is, with the inputs multiplied inside the step and autodiff through the scan.
"""
from __future__ import annotations

from jigsaws_tools.cli.common import import_tensorflow

tf = import_tensorflow()


class PerGateLSTM(tf.Module):
    def __init__(self, input_size: int, hidden: int, rng: tf.random.Generator, name: str):
        super().__init__(name=name)

        def u(shape):
            return tf.Variable(rng.uniform(shape, -0.1, 0.1))

        self.Wx = {g: u([input_size, hidden]) for g in "xifo"}
        self.Wm = {g: u([hidden, hidden]) for g in "xifo"}
        self.peep = {g: u([hidden]) for g in "ifo"}
        self.b = {g: tf.Variable(tf.zeros([hidden])) for g in "xifo"}
        self.hidden = hidden

    def __call__(self, x: tf.Tensor, resets: tf.Tensor) -> tf.Tensor:
        """x ``[T, B, F]``, resets ``[T, B, 1]`` float -> h ``[T, B, H]``."""
        zeros = tf.zeros([tf.shape(x)[1], self.hidden])

        def step(state, inputs):
            c, m = state
            xt, r = inputs
            c, m = c * (1 - r), m * (1 - r)
            g = tf.tanh(xt @ self.Wx["x"] + m @ self.Wm["x"] + self.b["x"])
            i = tf.sigmoid(xt @ self.Wx["i"] + m @ self.Wm["i"] + self.peep["i"] * c + self.b["i"])
            f = tf.sigmoid(xt @ self.Wx["f"] + m @ self.Wm["f"] + self.peep["f"] * c + self.b["f"])
            c = g * i + c * f
            o = tf.sigmoid(xt @ self.Wx["o"] + m @ self.Wm["o"] + self.peep["o"] * c + self.b["o"])
            return c, o * tf.tanh(c)

        return tf.scan(step, (x, resets), initializer=(zeros, zeros))[1]
