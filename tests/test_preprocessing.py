"""Each preprocessing step, their order, and the prediction and streaming paths."""
from dataclasses import replace

import numpy as np
import pytest

from jigsaws_tools.gestures import UNLABELLED
from jigsaws_tools.preprocessing import (Normalisation, PreprocessConfig, StreamingPreprocessor,
                                         causal_lowpass, lowpass, preprocess,
                                         preprocess_recording, resample, znormalise)

FS = 30.0


def _sine(hz, seconds=20.0):
    t = np.arange(int(seconds * FS)) / FS
    return np.sin(2 * np.pi * hz * t)[:, None]


def _interior(x):
    return x[60:-60]  # away from the filter's edge transients


def test_lowpass_removes_5hz_and_keeps_02hz():
    fast = lowpass(_sine(5.0), 1.5, 4)
    slow = lowpass(_sine(0.2), 1.5, 4)
    assert np.abs(_interior(fast)).max() < 1e-3
    assert np.abs(_interior(slow) - _interior(_sine(0.2))).max() < 1e-2


def test_lowpass_is_zero_phase():
    x = _sine(0.5)
    y = lowpass(x, 1.5, 4)
    lag = np.argmax(np.correlate(_interior(y)[:, 0], _interior(x)[:, 0], "full")) - (len(_interior(x)) - 1)
    assert lag == 0


@pytest.mark.parametrize("n", [1, 5, 6, 7, 12, 5556, 5557])
def test_resample_length_is_ceil_n_over_6(n):
    assert len(resample(np.zeros((n, 3)), 6)) == int(np.ceil(n / 6))


def test_znormalise_per_trial():
    rng = np.random.default_rng(0)
    x = rng.normal(5.0, 3.0, (400, 4)) * [1, 10, 0.1, 2]
    z = znormalise(x)
    np.testing.assert_allclose(z.mean(0), 0, atol=1e-9)
    np.testing.assert_allclose(z.std(0), 1, atol=1e-9)


def test_order_filter_then_drop_then_resample_then_normalise():
    rng = np.random.default_rng(1)
    n = 600
    x = rng.normal(size=(n, 2)) + _sine(0.3, n / FS)
    labels = np.zeros((n, 2), np.int64)
    labels[:50] = UNLABELLED
    config = PreprocessConfig()
    out, out_labels, frames = preprocess(x, labels, config)
    expected = znormalise(resample(lowpass(x, 1.5, 4)[50:], 6))
    np.testing.assert_allclose(out, expected, atol=1e-5)
    assert frames[0] == 51 and np.all(np.diff(frames) == 6)
    assert len(out_labels) == len(out) == int(np.ceil((n - 50) / 6))


def test_every_step_switchable():
    x = np.arange(40, dtype=float).reshape(20, 2)
    labels = np.zeros((20, 1), np.int64)
    labels[0] = UNLABELLED
    off = PreprocessConfig(lowpass=False, drop_unlabelled=False, resample_factor=1, normalise=False)
    out, out_labels, frames = preprocess(x, labels, off)
    np.testing.assert_array_equal(out, x.astype(np.float32))
    assert len(frames) == 20 and out_labels[0, 0] == UNLABELLED


# -- unlabelled recordings and causal (streaming) preprocessing ------------------------------------
def _recording(n=400, seed=2):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)) + 5 * _sine(0.3, n / FS) + [0.0, 10.0, -3.0]


def test_recording_keeps_every_frame_as_training_would_without_dropping():
    x = _recording(401)
    labels = np.full((401, 1), UNLABELLED)          # unknown labels, none dropped
    config = PreprocessConfig()
    inputs, frames = preprocess_recording(x, config)
    expected, _, expected_frames = preprocess(x, labels, replace(config, drop_unlabelled=False))
    np.testing.assert_array_equal(inputs, expected)
    np.testing.assert_array_equal(frames, expected_frames)
    assert frames[0] == 1 and np.all(np.diff(frames) == 6) and len(frames) == 67


def test_causal_lowpass_depends_only_on_the_past_and_filters():
    x = _recording()
    changed = x.copy()
    changed[200:] += 100.0
    np.testing.assert_array_equal(causal_lowpass(changed, 1.5, 4)[:200], causal_lowpass(x, 1.5, 4)[:200])
    fast = causal_lowpass(_sine(5.0), 1.5, 4)
    assert np.abs(fast[60:]).max() < 1e-2
    constant = np.full((50, 2), [3.0, -7.0])
    np.testing.assert_allclose(causal_lowpass(constant, 1.5, 4), constant)   # no start-up transient


def test_normalisation_fitted_on_one_recording_is_its_z_normalisation():
    x = _recording()
    stats = Normalisation.fit([x[:100], x[100:]])
    np.testing.assert_allclose(stats.apply(x), znormalise(x), atol=1e-12)
    with pytest.raises(ValueError, match="3 features"):
        stats.apply(x[:, :2])


@pytest.mark.parametrize("n", [1, 6, 7, 400])
def test_streaming_frame_by_frame_equals_the_causal_whole_recording(n):
    x = _recording(n)
    config = PreprocessConfig()
    stats = Normalisation.fit([_recording(300, seed=5)])
    stream = StreamingPreprocessor(config, stats)
    samples = [stream.push(frame) for frame in x]
    kept = [i + 1 for i, s in enumerate(samples) if s is not None]
    inputs, frames = preprocess_recording(x, config, causal=True, normalisation=stats)
    assert kept == frames.tolist()
    np.testing.assert_allclose(np.stack([s for s in samples if s is not None]), inputs,
                               rtol=1e-6, atol=1e-6)


def test_causal_preprocessing_needs_fixed_statistics():
    with pytest.raises(ValueError, match="fixed normalisation"):
        preprocess_recording(_recording(), PreprocessConfig(), causal=True)
    with pytest.raises(ValueError, match="fixed normalisation"):
        StreamingPreprocessor(PreprocessConfig(), None)
