"""Each preprocessing step, and their order."""
import numpy as np
import pytest

from jigsaws_tools.gestures import UNLABELLED
from jigsaws_tools.preprocessing import PreprocessConfig, lowpass, preprocess, resample, znormalise

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
