"""Sweep construction and the learning-rate schedule."""
import numpy as np
import pytest

from rnn_seg.optim import OptimConfig
from rnn_seg.sweeps import make_sweep, reset_flags, sweep_indices, sweeps_per_epoch


def test_wrapping_and_resets_as_in_original_docstring():
    sweep = make_sweep([np.array([1, 0]), np.array([1, 0, 0]), np.array([1, 0])])
    np.testing.assert_array_equal(sweep, [[1, 0, 1], [1, 0, 0], [1, 0, 1]])
    np.testing.assert_array_equal(reset_flags([2, 3, 2], 3),
                                  [[1, 0, 1], [1, 0, 0], [1, 0, 1]])


def test_each_pass_visits_every_sequence_in_a_new_order():
    n, b = 33, 5
    stream = [i for s in range(sweeps_per_epoch(n, b) * 3) for i in sweep_indices(n, b, 7, s)]
    first, second = stream[:n], stream[n:2 * n]
    assert sorted(first) == list(range(n)) and sorted(second) == list(range(n))
    assert first != second
    assert sweep_indices(n, b, 7, 11) == sweep_indices(n, b, 7, 11)
    assert sweep_indices(n, b, 8, 11) != sweep_indices(n, b, 7, 11)


def test_sweeps_per_epoch():
    assert sweeps_per_epoch(33, 5) == 7 and sweeps_per_epoch(35, 5) == 7 and sweeps_per_epoch(1, 5) == 1


def test_staircase_schedule_in_epochs_and_sweeps():
    epochs = OptimConfig(learning_rate=1.0, unit="epochs", total=120, decay_start=80, decay_every=40)
    assert epochs.learning_rate_at(80 * 7 - 1, 7) == 1.0
    assert epochs.learning_rate_at(80 * 7, 7) == 0.5
    assert epochs.learning_rate_at(120 * 7 - 1, 7) == 0.5
    sweeps = OptimConfig(unit="sweeps", total=600, decay_start=300, decay_every=50)
    assert [sweeps.learning_rate_at(s, 7) for s in (299, 300, 349, 350, 599)] == \
        [1.0, 0.5, 0.5, 0.25, 0.5 ** 6]
    assert sweeps.sweeps(600, 7) == 600 and epochs.sweeps(120, 7) == 840
    with pytest.raises(ValueError):
        OptimConfig(unit="iterations")
