"""A user's encoder: a Keras layer run by the engine as any encoder (``rnn_seg.encoders``).

The function or class a ``CustomEncoderConfig`` names is called once per model as
``build(input_size, config)`` and returns a Keras layer (a ``keras.layers.Layer``, a
``keras.Model`` included) mapping ``[B, T, input_size]`` float32 at the model's 5 Hz to
``[B, T, D]``: the same ``T`` (the heads label every sample), ``D`` fixed when the layer is built
(its output width, which the heads read). It is checked on a ``[2, PROBE_STEPS, input_size]``
input of zeros at once. Keras is seeded from the model's generator before the call
(``keras.utils.set_random_seed``), so a run's seed gives the same initial weights.

The engine runs the layer functionally (``Layer.stateless_call``) with any weights of its
``params()`` structure (its trainable variables, in Keras's order), so the engine's optimisers,
checkpoints, GradNorm and stacked steps treat it as their own encoder. Its sweeps are padded
(one sequence per row, zeros after its end): the layer gets ``mask`` ``[B, T]`` bool when its
``call`` takes one (Keras's recurrent layers then skip the padding) and its output is zeroed
after each sequence's end. Dropout (``keras.layers.Dropout`` and the recurrent layers' own) draws
from the engine's stateless seeds, one per sweep; no other non-trainable state is kept (a batch
normalisation's moving averages would never be updated), so a layer holding any is refused.
GradNorm's shared layer is the last sublayer with weights (the layer itself when it has none).
"""
from __future__ import annotations

import inspect

import tensorflow as tf

from .config import CustomEncoderConfig
from .convolution import mask_of
from .import_path import EncoderImportError, check_source, load_builder

#: Steps of the input a built layer is checked on.
PROBE_STEPS = 7
#: The name Keras gives a dropout seed generator's state variable.
_SEED_STATE = "seed_generator_state"


class _Held:
    """Holds the Keras layer out of the checkpoint's object graph: the engine checkpoints its
    variables under the encoder's own names (``KerasEncoder.weights``)."""

    def __init__(self, layer, shared: list):
        self.layer, self.shared = layer, shared


class KerasEncoder(tf.Module):
    """``[B, T, F]`` -> ``[B, T, output_size]`` through a user's Keras layer (module
    docstring)."""

    layout = "padded"    # one sequence per row, zeros after its end (rnn_seg.encoders)

    def __init__(self, input_size: int, config: CustomEncoderConfig, rng: tf.random.Generator):
        super().__init__(name="encoder")
        self.config = config
        check_source(config)
        layer = _built(config, input_size, rng)
        self.output_size = _output_width(config.path, layer, input_size)
        kept = [v for v in layer.non_trainable_variables if not _is_seed_state(v)]
        if kept:
            raise EncoderImportError(
                f"encoder {config.path}: the layer keeps non-trainable state "
                f"({', '.join(v.path for v in kept[:3])}), which the engine would never update; "
                "use a layer without it (e.g. LayerNormalization, not BatchNormalization)")
        self._held = _Held(layer, _last_sublayer_weights(layer))
        self.weights = [v.value for v in layer.trainable_variables]
        self._seed_shapes = [(v.shape, v.dtype) for v in layer.non_trainable_variables]
        self._takes_mask = "mask" in inspect.signature(layer.call).parameters

    @property
    def dropout_calls(self) -> int:
        """One stateless seed per training call, from which each dropout draws its own."""
        return 1 if self._seed_shapes else 0

    def params(self) -> list[tf.Variable]:
        return list(self.weights)

    def shared_variables(self) -> list[tf.Variable]:
        """GradNorm's ``W``: the weights of the layer's last sublayer that has any."""
        return list(self._held.shared)

    def apply(self, params: list[tf.Tensor], inputs: tf.Tensor, resets: tf.Tensor,
              dropout_seeds: tf.Tensor | None, valid: tf.Tensor | None = None) -> tf.Tensor:
        """The layer with weights ``params``.

        Args:
            params: ``params()``'s structure: one tensor per trainable variable.
            inputs: ``[B, T, F]`` float32, one sequence per row from step 0.
            resets: ``[B, T]`` bool; unused (a row holds one sequence).
            dropout_seeds: ``[1, 2]`` int64 stateless seed (``dropout_calls`` rows), or None:
                evaluation, the layer called with ``training=False``.
            valid: ``[B, T]`` bool, the real steps of each row; None = all.

        Returns:
            ``[B, T, output_size]`` float32, zero at the steps that are not valid.
        """
        del resets
        mask = mask_of(valid, inputs)
        training = dropout_seeds is not None
        states = [tf.cast(tf.random.experimental.stateless_fold_in(dropout_seeds[0], i), dtype)
                  if training else tf.zeros(shape, dtype)
                  for i, (shape, dtype) in enumerate(self._seed_shapes)]
        options = {"training": training}
        if self._takes_mask and valid is not None:
            options["mask"] = valid
        outputs, _ = self._held.layer.stateless_call(list(params), states, inputs * mask,
                                                     **options)
        return tf.cast(outputs, tf.float32) * mask


def _built(config: CustomEncoderConfig, input_size: int, rng: tf.random.Generator):
    """The layer ``config``'s builder returns, Keras seeded from ``rng``."""
    import keras

    builder = load_builder(config.path)
    keras.utils.set_random_seed(int(rng.uniform([], 0, 2 ** 31 - 1, dtype=tf.int64)))
    try:
        layer = builder(input_size, config)
    except Exception as error:          # the user's code may raise anything
        raise EncoderImportError(f"encoder {config.path}: building it failed "
                                 f"({type(error).__name__}: {error})") from None
    if not isinstance(layer, keras.layers.Layer):
        raise EncoderImportError(f"encoder {config.path}: returned a {type(layer).__name__}, "
                                 "not a Keras layer")
    return layer


def _output_width(path: str, layer, input_size: int) -> int:
    """``D`` of the layer's output on a ``[2, PROBE_STEPS, input_size]`` probe (which builds
    it); an ``EncoderImportError`` unless that output is ``[2, PROBE_STEPS, D]``."""
    expected = f"[2, {PROBE_STEPS}, D]"
    try:
        outputs = layer(tf.zeros([2, PROBE_STEPS, input_size]), training=False)
    except Exception as error:          # the user's code may raise anything
        raise EncoderImportError(f"encoder {path}: fails on a [2, {PROBE_STEPS}, {input_size}] "
                                 f"input ({type(error).__name__}: {error})") from None
    shape = getattr(outputs, "shape", None)
    shape = list(shape) if shape is not None else None
    if shape is None or len(shape) != 3 or shape[:2] != [2, PROBE_STEPS] or not shape[2]:
        raise EncoderImportError(
            f"encoder {path}: maps a [2, {PROBE_STEPS}, {input_size}] input to "
            f"{shape if shape is not None else type(outputs).__name__}, not {expected} "
            "(batch, time, channels: the same time steps, a fixed width)")
    return int(shape[2])


def _is_seed_state(variable) -> bool:
    return variable.name == _SEED_STATE


def _last_sublayer_weights(layer) -> list[tf.Variable]:
    """The trainable variables of the last sublayer of ``layer`` that has any (``layer``'s own
    when it has no sublayers)."""
    sublayers = [sub for sub in getattr(layer, "layers", []) if sub.trainable_variables]
    chosen = sublayers[-1] if sublayers else layer
    return [v.value for v in chosen.trainable_variables]
