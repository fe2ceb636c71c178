"""The convergence diagnostic tells a training loss still falling from a flat one."""
import numpy as np
import pandas as pd
import pytest

from rnn_seg.convergence import (ConvergenceCriterion, convergence, drop_interval,
                                  history_convergence, loss_drop, loss_drop_fit, verdict)

TOTAL = 60


def _noisy(curve: np.ndarray, seed: int, noise: float = 0.06) -> np.ndarray:
    """``curve`` with the multiplicative unit-to-unit noise of a real run (about 6 %)."""
    return curve * np.exp(np.random.default_rng(seed).normal(0, noise, curve.shape))


def test_a_steep_fall_is_flagged_and_a_flat_loss_passes():
    units = np.arange(1, TOTAL + 1)
    steep = _noisy(2.0 * np.exp(-units / 15), seed=0)           # -33 % per 6 units at the end
    flat = _noisy(0.3 + 0.0 * units, seed=1)
    for seed in range(20):                                       # whatever the noise
        assert not convergence(units, {"t": _noisy(2.0 * np.exp(-units / 15), seed)},
                               TOTAL)["converged"]
        assert convergence(units, {"t": _noisy(0.3 + 0.0 * units, seed)}, TOTAL)["converged"]
    assert loss_drop(units, steep, TOTAL) == pytest.approx(1 - np.exp(-6 / 15), abs=0.1)
    assert abs(loss_drop(units, flat, TOTAL)) < 0.05


def test_every_task_must_have_converged():
    units = np.arange(1, TOTAL + 1)
    result = convergence(units, {"gesture": 0.3 + 0 * units, "progress": 2.0 * np.exp(-units / 15)},
                         TOTAL)
    assert result["loss_drop"]["gesture"] == pytest.approx(0.0, abs=1e-9)
    assert result["max_loss_drop"] == pytest.approx(result["loss_drop"]["progress"])
    assert result["converged"] is False


def test_too_short_a_history_is_unknown():
    units = np.arange(1, 4)
    result = convergence(units, {"t": np.array([1.0, 0.5, 0.2])}, 3)
    assert result["converged"] is None and result["max_loss_drop"] is None


def test_window_follows_the_criterion():
    """Only the last ``window`` of the schedule counts: a fall before it is ignored."""
    units = np.arange(1, TOTAL + 1)
    early_fall = np.where(units < 40, 2.0, 0.3)
    assert loss_drop(units, early_fall, TOTAL) == pytest.approx(0.0, abs=1e-9)
    wide = ConvergenceCriterion(window=0.5)
    assert loss_drop(units, early_fall, TOTAL, wide) > 0.05


def test_history_table():
    history = pd.DataFrame({"n": np.arange(1, 11.0), "loss_gesture": np.linspace(1, 0.5, 10)})
    result = history_convergence(history, ["gesture"], 10, ConvergenceCriterion(window=0.5))
    assert result["converged"] is False and result["loss_drop"]["gesture"] > 0.05


def test_standard_error_covers_the_true_drop():
    """Under independent noise, drop +- t(0.975, n - 2) SE holds the true drop in about 95 % of
    runs (12 units in the window: 10 degrees of freedom)."""
    units = np.arange(1, TOTAL + 1)
    truth = 1 - np.exp(-6 / 40)                                  # exp(-n / 40): 14 % per 6 units
    t_quantile = 2.228                                           # scipy.stats.t.ppf(0.975, 10)
    covered = []
    for seed in range(400):
        drop, se = loss_drop_fit(units, _noisy(np.exp(-units / 40), seed), TOTAL)
        covered.append(abs(drop - truth) < t_quantile * se)
    assert 0.92 < np.mean(covered) < 0.98
    exact = loss_drop_fit(units, np.exp(-units / 40), TOTAL)
    assert exact == pytest.approx((truth, 0.0), abs=1e-9)


def test_convergence_reports_the_worst_tasks_standard_error():
    units = np.arange(1, TOTAL + 1)
    result = convergence(units, {"gesture": _noisy(0.3 + 0 * units, 0),
                                 "progress": _noisy(2.0 * np.exp(-units / 15), 1)}, TOTAL)
    assert result["max_loss_drop_se"] == result["loss_drop_se"]["progress"] > 0
    assert result["loss_drop_se"]["gesture"] > 0


def test_the_drop_interval_is_the_slopes_interval_carried_to_the_drop():
    """From ``loss_drop`` and its standard error alone: the slope's +-1.96 se interval."""
    units = np.arange(1, TOTAL + 1)
    losses = _noisy(np.exp(-units / 40), seed=3)
    drop, se = loss_drop_fit(units, losses, TOTAL)
    keep = units > 0.8 * TOTAL
    x, y = units[keep], np.log(losses[keep])
    slope, intercept = np.polyfit(x, y, 1)
    residuals = y - (slope * x + intercept)
    slope_se = np.sqrt(residuals @ residuals / (len(x) - 2) / ((x - x.mean()) @ (x - x.mean())))
    span = 0.1 * TOTAL
    expected = (1 - np.exp((slope + 1.96 * slope_se) * span),
                1 - np.exp((slope - 1.96 * slope_se) * span))
    assert drop_interval(drop, se) == pytest.approx(expected, rel=1e-3)
    low, high = drop_interval(0.05, 0.0)
    assert low == high == pytest.approx(0.05)


@pytest.mark.parametrize("fits, expected", [
    ([(0.01, 0.005)], "converged"),                       # interval about [0.0002, 0.020]
    ([(0.03, 0.013)], "undecided"),                       # holds 5 %
    ([(0.093, 0.016)], "still falling"),                  # Table I's APoc, fold F: [6.2, 12.3] %
    ([(0.01, 0.005), (0.093, 0.016)], "still falling"),   # one task still falling is enough
    ([(0.01, 0.005), (0.04, 0.01)], "undecided"),         # every task must be below
])
def test_three_way_verdict(fits, expected):
    assert verdict(fits, 0.05) == expected


def test_convergence_records_the_three_way_verdict_beside_the_point_verdict():
    units = np.arange(1, TOTAL + 1)
    flat = convergence(units, {"t": 0.3 + 0.0 * units}, TOTAL)
    assert flat["verdict"] == "converged" and flat["converged"] is True
    steep = convergence(units, {"t": _noisy(2.0 * np.exp(-units / 15), 0)}, TOTAL)
    assert steep["verdict"] == "still falling" and steep["converged"] is False
    near = convergence(units, {"t": _noisy(np.exp(-units * -np.log(0.95) / 6), 1, 0.1)}, TOTAL)
    assert near["verdict"] == "undecided"                  # 5 % per 6 units: on the threshold
    assert convergence(np.arange(1, 4), {"t": np.array([1.0, 0.5, 0.2])}, 3)["verdict"] is None
