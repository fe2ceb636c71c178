"""Encoders: what turns a sweep of kinematic inputs into the features every head reads.

An encoder maps ``inputs [B, T, F]`` (with ``resets [B, T]`` and, for sweeps padded at the end,
``valid [B, T]``) to ``features [B, T, D]``, through ``apply(params, inputs, resets,
dropout_seeds, valid)`` with any weights of its ``params()`` structure; ``dropout_calls`` says how
many stateless seeds a training call takes. A run's configuration chooses one by its ``kind``
(``--encoder``, a grid spec's ``encoder``; ``rnn_seg.encoders.config``):

* ``lstm``: DiPietro et al.'s peephole (Bi)LSTM with its hand-written backward pass
  (``rnn_seg.lstm.RecurrentEncoder``, configured by ``rnn_seg.config.EncoderConfig``). Its sweeps
  are *wrapped*: shorter sequences repeated to the longest, the state reset at each copy;
* ``ed-tcn``: Lea et al.'s encoder-decoder TCN (``ed_tcn``);
* ``ms-tcn``: Farha & Gall's multi-stage TCN (``ms_tcn``), whose later stages refine every
  head's predictions (``ms_tcn.Refinement``, built by ``rnn_seg.model``).
* ``custom``: a user's own Keras layer, named by its import path ``package.module:name``
  (``import_path``: found, hashed and imported; ``keras_layer``: run as the engine's encoder;
  docs/YOUR_METHOD.md).

The convolutional encoders and a user's take *padded* sweeps (``layout = "padded"``): one sequence per row,
zeros after its end, ``valid`` marking its steps (``convolution``). Online (``bidirectional``
False) means a forward LSTM or causal convolutions: the features at step t read steps <= t.

Modules: ``config`` (the TCNs' configurations and reference schedules; no TensorFlow),
``registry`` (``build_encoder``: a configuration's encoder), ``convolution`` (temporal
convolutions and their helpers), ``ed_tcn``, ``ms_tcn``, ``import_path`` (no TensorFlow),
``keras_layer``. Importing the package loads no
TensorFlow (``jigsaws_tools.lazy``).
"""
from jigsaws_tools.lazy import lazy_exports

#: Public name -> the submodule defining it, imported on first use (``jigsaws_tools.lazy``).
_PUBLIC = {
    "ENCODERS": "config",
    "EDTCNConfig": "config",
    "MSTCNConfig": "config",
    "build_encoder": "registry",
}
__all__ = sorted(_PUBLIC)
__getattr__ = lazy_exports(__name__, _PUBLIC)
