"""NumPy reference of DiPietro's LSTM cell (one direction), written step by step from the equations."""
import numpy as np


def sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))


def lstm_forward(x, resets, W_x, W_h, peep, b):
    """x ``[B, T, F]``, resets ``[B, T]`` bool -> h ``[B, T, H]`` (float64)."""
    B, T, _ = x.shape
    H = W_h.shape[0]
    c = np.zeros((B, H))
    h = np.zeros((B, H))
    out = np.zeros((B, T, H))
    for t in range(T):
        keep = ~resets[:, t:t + 1]
        c, h = c * keep, h * keep
        z = x[:, t] @ W_x + h @ W_h + b
        zg, zi, zf, zo = np.split(z, 4, axis=1)
        g = np.tanh(zg)
        i = sigmoid(zi + peep[0] * c)
        f = sigmoid(zf + peep[1] * c)
        c = g * i + c * f
        o = sigmoid(zo + peep[2] * c)
        h = o * np.tanh(c)
        out[:, t] = h
    return out


def bidirectional_forward(x, resets, fw, rv, mode):
    """Concatenated forward and reverse outputs ``[B, T, 2H]``; ``mode`` as in rnn_seg.lstm."""
    if mode == "original":
        rv_resets = resets
    else:
        rv_resets = np.concatenate([resets[:, 1:], np.ones_like(resets[:, :1])], axis=1)
    forward = lstm_forward(x, resets, *fw)
    reverse = lstm_forward(x[:, ::-1], rv_resets[:, ::-1], *rv)[:, ::-1]
    return np.concatenate([forward, reverse], axis=2)


def tf_lstm_forward(x, resets, W_x, W_h, peep, b):
    """The same cell in TensorFlow ops, step by step, for gradients by autodiff (the reference
    for rnn_seg's hand-written backward pass). x ``[B, T, F]``, resets ``[B, T]`` bool."""
    import tensorflow as tf

    keep = 1.0 - tf.cast(resets, x.dtype)[:, :, None]
    c = h = tf.zeros([x.shape[0], W_h.shape[0]], x.dtype)
    out = []
    for t in range(x.shape[1]):
        c, h = c * keep[:, t], h * keep[:, t]
        zg, zi, zf, zo = tf.split(x[:, t] @ W_x + h @ W_h + b, 4, axis=1)
        g, i, f = tf.tanh(zg), tf.sigmoid(zi + peep[0] * c), tf.sigmoid(zf + peep[1] * c)
        c = g * i + c * f
        h = tf.sigmoid(zo + peep[2] * c) * tf.tanh(c)
        out.append(h)
    return tf.stack(out, axis=1)
