"""What a design of folds x seeds can detect: the variance of a per-fold difference split into
the seeds' part and the folds' part, each estimate with its interval, and the sign-flip test's
power as seeds or folds are added.

The model is the one ``paired.power`` assumes, normal throughout. Side ``j`` of a contrast (``X``
or ``Y``, coefficient ``c_j = +-1``) scores ``mu_jf + e_jfs`` on fold ``f`` and seed ``s``, the
seed noise ``e_jfs ~ N(0, sigma_j^2)`` independent of everything else. The per-fold difference
of the seed means is then ``d_f = delta + b_f + sum_j c_j ebar_jf``: ``b_f ~ N(0, tau^2)`` is the
effect varying from one test user to another (the fold-by-treatment variance), and with ``k_j``
seeds per side ``var(d_f) = tau^2 + sum_j sigma_j^2 / k_j``. Averaging more seeds shrinks the
second term only; ``tau^2`` stays whatever the number of seeds.

Estimates (``VarianceSplit``), over the ``n`` paired folds:

* ``V``, the sample variance of ``d`` (``n - 1`` degrees of freedom);
* ``S``, what the seeds add to it: per side the within-fold variance over its seeds (the mean
  over the folds with 2 or more seeds, ``sigma_j^2``'s estimate ``s_j^2``) times the mean over
  folds of ``1 / k_j``, summed over the sides (``paired.PairedResult.seed_variance``);
* the **seed share** ``S / V`` (``ratio``; ``claims.csv``'s ``seed_share`` clips it to 1, as a
  share cannot exceed 1 while its estimate can) and ``tau^2 = max(0, V - S)``.

**The seed share's interval.** Within-fold deviations and fold means of normal data are
independent, so ``S`` and ``V`` are: ``(n - 1) V / var(d) ~ chi2(n - 1)`` and, by
Satterthwaite's approximation for a sum of independent scaled chi-square variables,
``nu S / E[S] ~ chi2(nu)`` with ``nu = S^2 / sum_j (w_j s_j^2)^2 / df_j`` (``w_j`` the mean of
``1 / k_j``, ``df_j`` side ``j``'s degrees of freedom). Hence ``(S / V) / share ~ F(nu, n - 1)``
and the interval is ``S / V`` divided by the F distribution's upper and lower quantiles, clipped
to [0, 1] (``share_interval``); exact for one side, approximate for two (nothing random enters).
The standard deviation of ``d`` has the usual chi-square interval (``sd_interval``).

**Power.** ``paired.power``: the probability that the exact sign-flip test over ``n`` folds
rejects "no difference" in the expected direction when the fold differences are normal with the
given mean and standard deviation; with ``k`` seeds per side the standard deviation is
``sqrt(tau^2 + sum_j s_j^2 / k)`` (``sd_with``), whose limit as seeds grow, ``tau``, sets the
**ceiling** no number of seeds can pass; only more folds (test users) raise it. **Holm's
correction** over a family of ``m`` endpoints rejects an endpoint at ``p <= alpha / m`` whatever
the others give, and at most at ``p <= alpha`` (all others rejected first), so its power lies
between the power at level ``alpha / m`` (``holm_config``: Holm's first step, Bonferroni) and
the test's power alone; where the others are not rejected it is the lower end.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy import stats

from .paired import (Contrast, PairedResult, SignFlip, StatsConfig, paired, power,
                     seed_values)


@dataclass(frozen=True)
class SideNoise:
    """One side's seed noise on the paired folds."""

    variance: float     # within-fold variance over its seeds, mean over folds with 2+ seeds
    df: float           # the degrees of freedom of that mean (Satterthwaite over the folds)
    weight: float       # mean over the folds of 1 / seeds: what averaging its seeds leaves


@dataclass(frozen=True)
class VarianceSplit:
    """The per-fold differences of a contrast (``result``) and their variance split into the
    seeds' part and the folds' part (module docstring). Variances in squared points."""

    result: PairedResult
    sides: tuple[SideNoise, ...]

    @property
    def total(self) -> float:
        """``V``: the sample variance of the per-fold differences."""
        return self.result.sd ** 2

    @property
    def seed(self) -> float:
        """``S``: what the seeds' noise adds to ``V`` at the runs' numbers of seeds."""
        return self.result.seed_variance

    @property
    def ratio(self) -> float:
        """``S / V``, unclipped (above 1 when the folds' part is estimated below 0)."""
        return self.seed / self.total if self.total > 0 else math.nan

    @property
    def share(self) -> float:
        """The seed share, ``ratio`` clipped to 1 (``PairedResult.seed_share``)."""
        return min(1.0, self.ratio)

    @property
    def fold(self) -> float:
        """``tau^2``'s estimate, ``max(0, V - S)``: what no number of seeds removes."""
        return max(0.0, self.total - self.seed)

    @property
    def one_seed(self) -> float:
        """What the seeds' noise would add to ``V`` with one seed per side: ``sum_j s_j^2``."""
        return sum(side.variance for side in self.sides)

    @property
    def seed_df(self) -> float:
        """``nu``, Satterthwaite's degrees of freedom of ``S``."""
        return self.seed ** 2 / sum((s.weight * s.variance) ** 2 / s.df for s in self.sides)

    def share_interval(self, confidence: float) -> tuple[float, float]:
        """The seed share's interval at ``confidence`` (``F(nu, n - 1)``), clipped to [0, 1]."""
        tail = (1 - confidence) / 2
        folds_df = self.result.pairs - 1
        return (min(1.0, self.ratio / stats.f.ppf(1 - tail, self.seed_df, folds_df)),
                min(1.0, self.ratio / stats.f.ppf(tail, self.seed_df, folds_df)))

    def sd_interval(self, confidence: float) -> tuple[float, float]:
        """The interval of the standard deviation of the per-fold differences (chi-square)."""
        tail, df = (1 - confidence) / 2, self.result.pairs - 1
        return (self.result.sd * math.sqrt(df / stats.chi2.ppf(1 - tail, df)),
                self.result.sd * math.sqrt(df / stats.chi2.ppf(tail, df)))

    def sd_with(self, seeds: float, seed_share: float | None = None) -> float:
        """The standard deviation of the per-fold differences with ``seeds`` per side
        (``math.inf``: ``tau``), at the estimated split or at another ``seed_share`` of ``V``
        (e.g. an end of its interval)."""
        fold, one_seed = self.fold, self.one_seed
        if seed_share is not None:
            fold = self.total * (1 - seed_share)
            one_seed *= self.total * seed_share / self.seed
        return math.sqrt(fold + (0.0 if math.isinf(seeds) else one_seed / seeds))


def variance_split(runs: pd.DataFrame, contrast: Contrast, metric: str,
                   config: StatsConfig = StatsConfig()) -> VarianceSplit:
    """``contrast`` on ``metric`` paired over folds (``paired.paired``), its variance split.

    Args:
        runs: one row per run (``collect.run_rows``), 2 or more seeds per side on some fold.
        contrast: e.g. ``Contrast(ConfigId("APc"), ConfigId("A"))``.
        metric: a metric column, e.g. ``gesture_edit``.
        config: the test's level and the power simulation's settings.

    Raises:
        paired.NotPaired: as ``paired.paired``.
        ValueError: a side has one seed on every fold (the split is unknown).
    """
    result = paired(runs, contrast, metric, config)
    if math.isnan(result.seed_variance):
        raise ValueError(f"{contrast.label} on {metric}: one seed per fold on a side, so the "
                         "seeds' part of the variance is unknown")
    sides = tuple(_side_noise([values[fold] for fold in result.folds])
                  for values in (seed_values(runs, side, metric) for side in contrast.terms()))
    return VarianceSplit(result, sides)


def _side_noise(folds: list[np.ndarray]) -> SideNoise:
    """A side's seed noise from its values over its seeds on each paired fold."""
    repeated = [values for values in folds if len(values) > 1]
    variance = float(np.mean([np.var(values, ddof=1) for values in repeated]))
    df = len(repeated) ** 2 / sum(1 / (len(values) - 1) for values in repeated)
    return SideNoise(variance, df, float(np.mean([1 / len(values) for values in folds])))


def holm_config(config: StatsConfig, family_size: int) -> StatsConfig:
    """``config`` at Holm's first-step level, ``alpha / family_size``: the power at it is the
    least an endpoint's power under Holm's correction can be (module docstring)."""
    return replace(config, confidence=1 - config.alpha / family_size)


def detection_power(folds: int, gain: float, sd: float, config: StatsConfig) -> float:
    """``paired.power`` of the test over ``folds`` at ``config``'s level in the direction of
    ``gain``; 1 when the fold differences do not vary (``sd`` 0) and the test can reject."""
    sign = 1 if gain >= 0 else -1
    if sd == 0:
        low, high = SignFlip(np.full(folds, gain), config.confidence).interval()
        return float(low > 0 if sign > 0 else high < 0)
    return power(folds, gain, sd, sign, config)
