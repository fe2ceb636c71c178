"""An encoder of your own: a small bidirectional GRU, trained through the project's heads.

Train the paper's models on it by its import path (docs/YOUR_METHOD.md, "Your own encoder")::

    PYTHONPATH=examples multitask-train --synthetic --encoder gru_encoder:build --variant APc \\
        --epochs 20 --out runs/gru

The engine calls ``build(input_size, config)`` once per model and trains, evaluates, predicts
and exports the layer it returns like its own encoders: ``[batch, time, input_size]`` kinematic
features at 5 Hz in, ``[batch, time, width]`` features out, one per input sample.
"""
import keras

#: Units per direction: the layer returns 2 * UNITS features per sample.
UNITS = 32
DROPOUT = 0.2


def build(input_size: int, config) -> keras.Model:
    """A projection, dropout and a GRU over time (forward only when ``config.causal``, an online
    model asked for by ``--direction forward``), then a layer normalisation.

    Args:
        input_size: kinematic features per sample (``F``).
        config: the run's ``rnn_seg.encoders.config.CustomEncoderConfig`` (``path``,
            ``source_sha256``, ``causal``).

    Returns:
        A Keras model ``[B, T, input_size]`` -> ``[B, T, 2 * UNITS]`` (``UNITS`` when causal);
        it takes the engine's ``mask`` of the real steps, so padding does not reach them.
    """
    inputs = keras.Input((None, input_size))
    x = keras.layers.Dense(UNITS, activation="tanh")(inputs)
    x = keras.layers.Dropout(DROPOUT)(x)
    gru = keras.layers.GRU(UNITS, return_sequences=True)
    x = gru(x) if config.causal else keras.layers.Bidirectional(gru)(x)
    outputs = keras.layers.LayerNormalization()(x)
    return keras.Model(inputs, outputs, name="gru_encoder")
