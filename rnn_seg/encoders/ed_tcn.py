"""Lea et al.'s encoder-decoder temporal convolutional network (ED-TCN, CVPR 2017).

For ``filters = (F_1, ..., F_L)`` and kernel ``k`` (``EDTCNConfig``)::

    encoder layer l = 1..L:   x = pool(norm(relu(drop(conv_k(x)))))       F_l channels
    decoder layer l = L..1:   x = norm(relu(drop(conv_k(upsample(x)))))   F_l channels

``conv_k`` a temporal convolution of ``k`` samples (``convolution.conv``; causal when online),
``drop`` spatial dropout (whole channels), ``norm`` the division by each step's largest
activation, ``pool`` max pooling by 2 and ``upsample`` its inverse (causal when online, so that
no future sample leaks through a pooled pair). The sequence is padded with zeros to a multiple of
``2**L`` steps and cut back after the decoder. ``[B, T, F]`` -> ``[B, T, F_1]``; the heads read
the last decoder layer, which is GradNorm's shared layer.

Padding (``EDTCNConfig.padding``): ``masked`` (the engine's) multiplies every layer's output by
the mask of the real steps, so a sequence's outputs do not depend on its row's padding.
``reference`` is Lea et al.'s (``TCN_main.py``): the steps after a sequence's end hold -1 in
every feature and no layer is masked, so the -1 steps reach the last real steps through the
convolutions; only the loss is masked (``Task.loss``'s ``valid``). They padded every sequence
to the longest trial; here every sequence gets at least ``reference_reach`` steps of -1 (more
than one output step reads of the future, ``2 * ceil((k-1)/2) * (2**L - 1) + 2**L``), which gives
every real step the output their padding gives it, whatever its row's length, but for a trial
so nearly the longest that their padding ended within that reach (its last steps read the
convolutions' zero padding there).
"""
from __future__ import annotations

import tensorflow as tf

from .config import EDTCNConfig
from .convolution import (Conv, ConvParams, channel_normalise, conv, dropout, mask_of, max_pool,
                          pad_to_multiple, upsample)

EDTCNParams = dict[str, list[ConvParams]]     # "encoder", "decoder" -> one entry per layer


class EDTCNEncoder(tf.Module):
    """``[B, T, F]`` -> ``[B, T, filters[0]]`` (module docstring)."""

    layout = "padded"    # one sequence per row, zeros after its end (rnn_seg.encoders)

    def __init__(self, input_size: int, config: EDTCNConfig, rng: tf.random.Generator):
        super().__init__(name="encoder")
        self.config = config
        widths = config.filters
        down = [input_size, *widths]
        self.encoder_layers = [Conv(config.kernel, down[i], widths[i], rng, "glorot",
                                    name=f"encoder{i}") for i in range(len(widths))]
        up = [widths[-1], *reversed(widths)]
        self.decoder_layers = [Conv(config.kernel, up[i], up[i + 1], rng, "glorot",
                                    name=f"decoder{i}") for i in range(len(widths))]

    @property
    def dropout_calls(self) -> int:
        """One spatial dropout mask per layer."""
        return 2 * len(self.config.filters)

    def params(self) -> EDTCNParams:
        return {"encoder": [c.params() for c in self.encoder_layers],
                "decoder": [c.params() for c in self.decoder_layers]}

    def shared_variables(self) -> list[tf.Variable]:
        """GradNorm's ``W``: the last decoder layer's weights (what the heads read)."""
        return list(self.decoder_layers[-1].trainable_variables)

    def apply(self, params: EDTCNParams, inputs: tf.Tensor, resets: tf.Tensor,
              dropout_seeds: tf.Tensor | None, valid: tf.Tensor | None = None) -> tf.Tensor:
        """The encoder with weights ``params``.

        Args:
            params: ``params()``'s structure.
            inputs: ``[B, T, F]`` float32, one sequence per row from step 0.
            resets: ``[B, T]`` bool; unused (a row holds one sequence).
            dropout_seeds: ``[dropout_calls, 2]`` int64 stateless seeds, encoder layers first;
                None = no dropout.
            valid: ``[B, T]`` bool, the real steps of each row; None = all.

        Returns:
            ``[B, T, filters[0]]`` float32, zero at the steps that are not valid.
        """
        del resets
        if self.config.padding == "reference":
            return self._apply_unmasked(params, inputs, dropout_seeds, valid)
        config, depth = self.config, len(self.config.filters)
        steps = tf.shape(inputs)[1]
        mask = pad_to_multiple(mask_of(valid, inputs), 2 ** depth)
        x = pad_to_multiple(inputs, 2 ** depth) * mask
        masks = [mask]
        for i, p in enumerate(params["encoder"]):
            x = self._block(x, p, self._seed(dropout_seeds, i)) * masks[-1]
            x, masks = max_pool(x), [*masks, max_pool(masks[-1])]
            x = x * masks[-1]
        for i, p in enumerate(params["decoder"]):
            mask = masks[depth - 1 - i]
            x = upsample(x, config.causal) * mask
            x = self._block(x, p, self._seed(dropout_seeds, depth + i)) * mask
        return x[:, :steps]

    @property
    def reference_reach(self) -> int:
        """Steps of -1 after every sequence with ``reference`` padding: ``kernel * 2**(L+1)``,
        more than the future steps one output step reads (module docstring)."""
        return self.config.kernel * 2 ** (len(self.config.filters) + 1)

    def _apply_unmasked(self, params: EDTCNParams, inputs: tf.Tensor,
                        dropout_seeds: tf.Tensor | None, valid: tf.Tensor | None) -> tf.Tensor:
        """``apply`` with Lea et al.'s padding (module docstring): ``[B, T, F]`` ->
        ``[B, T, filters[0]]``, not zero after a sequence's end."""
        depth = len(self.config.filters)
        steps = tf.shape(inputs)[1]
        x = tf.where(mask_of(valid, inputs) > 0, inputs, -1.0)
        x = tf.pad(x, [[0, 0], [0, self.reference_reach], [0, 0]], constant_values=-1.0)
        x = pad_to_multiple(x, 2 ** depth, value=-1.0)
        for i, p in enumerate(params["encoder"]):
            x = max_pool(self._block(x, p, self._seed(dropout_seeds, i)))
        for i, p in enumerate(params["decoder"]):
            x = self._block(upsample(x, self.config.causal), p,
                            self._seed(dropout_seeds, depth + i))
        return x[:, :steps]

    def _block(self, x: tf.Tensor, params: ConvParams, seed: tf.Tensor | None) -> tf.Tensor:
        """Convolution, spatial dropout, normalised ReLU."""
        x = conv(x, params, causal=self.config.causal)
        x = dropout(x, self.config.dropout, seed, spatial=True)
        return channel_normalise(tf.nn.relu(x))

    @staticmethod
    def _seed(seeds: tf.Tensor | None, i: int) -> tf.Tensor | None:
        return None if seeds is None else seeds[i]
