"""Paired statistics over LOUO folds: is configuration X better than Y on a metric, and by how much?

The unit of pairing is the LOUO fold (one test user): every configuration is evaluated on the same
held-out surgeon, so fold-to-fold differences in difficulty (the 5-8 point standard deviations of
the paper's tables) cancel in the per-fold difference. Within a fold each side is the mean over
its seeds; seeds are not paired (seed k of X and seed k of Y share nothing but a number).

For a contrast (``X - Y``, or a difference of differences ``(X1 - Y1) - (X2 - Y2)``) on a metric,
one procedure gives the test and the interval, so that they cannot disagree:

* the per-fold differences ``d`` on the folds every side ran (the others are dropped and named),
  their mean, standard deviation and ``effect_dz`` = mean / sd;
* the **exact paired sign-flip (permutation) test** of the mean difference: under the null
  hypothesis "the difference is ``d0``", each ``d_i - d0`` is as likely positive as negative, so the
  ``2^n`` sign vectors are equally likely; the two-sided p-value is the share of sign vectors ``s``
  with ``|sum s_i (d_i - d0)| >= |sum (d_i - d0)|``. Every vector is enumerated (``2^8 = 256`` for
  8 folds): no random draw enters. The smallest p is ``2 / 2^n`` (0.0078 for 8 folds, 0.0156 for 7);
* the **confidence interval** is the same test inverted: the shifts ``d0`` it does not reject at
  level ``1 - confidence``. It is computed exactly: a sign vector counts at ``d0`` exactly when
  ``d0`` lies between the mean of ``d`` over its flipped folds and the mean over the others
  (both sides are linear in ``d0``), so the p-value at any ``d0`` and the interval's ends come
  from the same sorted subset means. Values within ``TIES`` of each other count as equal (a tie
  counts towards p, as ``>=`` says), so that float rounding of the seed means (about 1e-14 for
  scores near 100) never decides whether a sign vector counts, e.g. when a fold difference is 0
  or some folds' differences sum to 0; the interval's ends lie ``TIES`` beyond the subset means.
  ``p(0) <= alpha`` if and only if the interval excludes 0, by construction; coverage is exact
  (``1 - 12/256`` = 95.3 % at 8 folds) whenever the fold differences are symmetric about their
  mean;
* the variance of ``d`` split into a **seed share** (each side's within-fold variance over its
  seeds, divided by its number of seeds: what averaging the seeds leaves in a fold's mean) and a
  **fold share** (the rest: how the effect itself varies from one test user to another). With one
  seed per side the split is unknown.

``power`` is the probability that the same test, at the same level, rejects in a given direction
when the fold differences are normal with a given mean and standard deviation. The test and its
interval are equivariant (shifting and scaling ``d`` shifts and scales the interval), so one
simulation per number of folds serves every claim: ``power_samples`` standard normal vectors from
``numpy.random.default_rng(power_seed)``, whose exact intervals are kept; the Monte-Carlo standard
error is at most ``0.5 / sqrt(power_samples)`` (0.0005 for the default 10^6).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Sequence

import numpy as np
import pandas as pd

from jigsaws_tools.annotations import ANNOTATION_VERSIONS

from ...grid.spec import DIRECTIONS
from ..runs.collect import CONVERGENCE_COLUMNS, KEY_COLUMNS, per_class
from ..runs.pooling import is_architecture

UNIT_OF_PAIRING = "LOUO fold (test user); each side averaged over its seeds within the fold"
#: The most folds the exact test enumerates (2^n sign vectors).
MAX_EXACT_FOLDS = 16
#: How close (in the differences' unit) a shift and a subset mean must be to count as equal in
#: the sign-flip test: far above float rounding, far below any score's resolution.
TIES = 1e-10


@dataclass(frozen=True)
class ConfigId:
    """One configuration of the grid: its runs
    ``runs/<annotations>/<direction>/<variant>-<weighting>/seed<k>/<fold>``; with an
    ``architecture`` (``pooling.architecture``: ``lstm-128``, ``ed-tcn``, ...), those of that
    architecture's grid in a table of several (its runs carry an ``architecture`` column)."""

    variant: str
    weighting: str = "fixed"
    annotations: str = "revised"
    direction: str = "bidirectional"
    architecture: str = ""          # "": the one architecture of a grid's table

    @classmethod
    def parse(cls, text: str) -> ConfigId:
        """``[architecture/][annotations/][direction/]<variant>-<weighting>`` as in the grid's
        run folders, e.g. ``APc-fixed``, ``original/APoc-gradnorm``, ``revised/forward/A-fixed``,
        ``ed-tcn/APc-fixed``; the weighting may be left out (``fixed``). Unnamed parts default
        to revised labels, bidirectional, the table's one architecture."""
        *prefix, config = text.split("/")
        variant, _, weighting = config.partition("-")
        values = {"variant": variant, "weighting": weighting or "fixed"}
        for part in prefix:
            if part in ANNOTATION_VERSIONS:
                values["annotations"] = part
            elif part in DIRECTIONS:
                values["direction"] = part
            elif is_architecture(part):
                values["architecture"] = part
            else:
                raise ValueError(f"configuration {text!r}: {part!r} is neither an annotation "
                                 f"version ({', '.join(ANNOTATION_VERSIONS)}), a direction "
                                 f"({', '.join(DIRECTIONS)}) nor an architecture (lstm-128, "
                                 "ed-tcn, ms-tcn)")
        if not variant or len(prefix) > 3:
            raise ValueError(f"configuration {text!r}: expected "
                             "[annotations/][direction/]<variant>-<weighting>, e.g. APc-fixed")
        return cls(**values)

    @property
    def label(self) -> str:
        """``<variant>-<weighting>``, prefixed by the architecture, the labels and the direction
        where they are not the defaults (one architecture, revised, bidirectional)."""
        prefix = [p for p, default in ((self.architecture, ""), (self.annotations, "revised"),
                                       (self.direction, "bidirectional")) if p != default]
        return "/".join([*prefix, f"{self.variant}-{self.weighting}"])

    def select(self, runs: pd.DataFrame) -> pd.DataFrame:
        """This configuration's rows of a per-run table (``collect.run_rows``; of a table of
        several architectures, with an ``architecture`` column, for one with an architecture)."""
        chosen = ((runs.annotations == self.annotations) & (runs.direction == self.direction)
                  & (runs.variant == self.variant) & (runs.weighting == self.weighting))
        if self.architecture:
            if "architecture" not in runs.columns:
                return runs.iloc[:0]
            chosen &= runs.architecture == self.architecture
        return runs[chosen]


@dataclass(frozen=True)
class Contrast:
    """``x - y`` per fold, or the difference of differences ``(x - y) - (minus[0] - minus[1])``
    (e.g. APr's GradNorm gain minus APc's)."""

    x: ConfigId
    y: ConfigId
    minus: tuple[ConfigId, ConfigId] | None = None

    def terms(self) -> dict[ConfigId, int]:
        """Configuration -> coefficient (+1 / -1) in the per-fold value."""
        terms: dict[ConfigId, int] = {}
        pairs = [(self.x, self.y)] + ([(self.minus[1], self.minus[0])] if self.minus else [])
        for plus, minus in pairs:
            terms[plus] = terms.get(plus, 0) + 1
            terms[minus] = terms.get(minus, 0) - 1
        terms = {config: coef for config, coef in terms.items() if coef}
        if not terms:
            raise ValueError(f"{self.label}: the contrast is zero by construction "
                             "(a configuration compared with itself)")
        return terms

    @property
    def configs(self) -> tuple[ConfigId, ...]:
        return (self.x, self.y) + (self.minus or ())

    @property
    def label(self) -> str:
        difference = f"{self.x.label} - {self.y.label}"
        if self.minus is None:
            return difference
        return f"({difference}) - ({self.minus[0].label} - {self.minus[1].label})"


@dataclass(frozen=True)
class StatsConfig:
    """The test's level and the power simulation's settings. Nothing random enters a test, an
    interval or a verdict; ``power_seed`` seeds the power simulation alone."""

    confidence: float = 0.95
    power_samples: int = 1_000_000
    power_seed: int = 0

    method = ("exact paired sign-flip (permutation) test of the mean fold difference over all "
              "2^n sign vectors; the interval inverts the same test")

    def __post_init__(self):
        if not 0 < self.confidence < 1:
            raise ValueError(f"confidence must be in (0, 1) (value: {self.confidence})")
        if self.power_samples < 1000:
            raise ValueError(f"power_samples must be >= 1000 (value: {self.power_samples})")

    @property
    def alpha(self) -> float:
        return 1 - self.confidence

    @property
    def power_error(self) -> float:
        """The largest Monte-Carlo standard error of a simulated power (at power 0.5)."""
        return 0.5 / math.sqrt(self.power_samples)


class NotPaired(ValueError):
    """The runs hold no fold on which every side of a contrast has a value."""


class SignFlip:
    """The exact sign-flip test of the mean of ``differences`` ``[n]`` and its inverted interval.

    Each of the ``2^(n-1) - 1`` splits of the folds into two non-empty groups (a sign vector and
    its negation are one split) counts towards the p-value at ``d0`` when ``d0`` lies between the
    two groups' means (``low``, ``high``), to within ``TIES``; the two constant sign vectors
    always count."""

    def __init__(self, differences, confidence: float = 0.95):
        d = np.asarray(differences, float)
        if not 1 <= d.size <= MAX_EXACT_FOLDS:
            raise ValueError(f"the exact sign-flip test takes 1 to {MAX_EXACT_FOLDS} paired folds "
                             f"(value: {d.size})")
        self.n, self.alpha = d.size, 1 - confidence
        groups = _split_masks(d.size)                                     # [M, n] bool
        sizes = groups.sum(axis=1)
        flipped = (groups @ d) / sizes
        others = (~groups @ d) / (d.size - sizes)
        self.low = np.sort(np.minimum(flipped, others))
        self.high = np.sort(np.maximum(flipped, others))
        self.half = 2 ** (d.size - 1)                                     # sign vectors / 2
        # the fewest splits that must count at d0 for the test not to reject it
        self.needed = next(k for k in range(self.half + 1) if (1 + k) / self.half > self.alpha)

    def p_value(self, d0: float = 0.0) -> float:
        """Two-sided p-value of the hypothesis "the mean difference is ``d0``"."""
        counting = np.searchsorted(self.low, d0 + TIES, side="right") - np.searchsorted(
            self.high, d0 - TIES, side="left")
        return (1 + int(counting)) / self.half

    def interval(self) -> tuple[float, float]:
        """The ``d0`` the test does not reject (infinite when it can reject none)."""
        if self.needed == 0:
            return -math.inf, math.inf
        return (float(self.low[self.needed - 1]) - TIES,
                float(self.high[-self.needed]) + TIES)

    @property
    def smallest_p(self) -> float:
        return 1 / self.half


@lru_cache(maxsize=None)
def _split_masks(n: int) -> np.ndarray:
    """``[2^(n-1) - 1, n]``: every split of ``n`` folds into two non-empty groups, as the mask of
    the group without the last fold."""
    codes = np.arange(1, 2 ** (n - 1))
    return ((codes[:, None] >> np.arange(n)) & 1).astype(bool)


@dataclass(frozen=True)
class PairedResult:
    """A contrast on one metric, paired by fold. Differences are in the metric's unit (percent
    points for every score of ``collect.METRICS``)."""

    contrast: str
    metric: str
    folds: tuple[str, ...]              # the paired folds, sorted
    differences: tuple[float, ...]      # per paired fold, same order
    dropped: dict[str, str]             # fold -> the sides that lack it
    seeds: tuple[int, int]              # fewest and most seeds of a side on a paired fold
    seed_variance: float                # what the seeds' noise adds to var(d); NaN with 1 seed
    config: StatsConfig
    unit: str = UNIT_OF_PAIRING

    @property
    def pairs(self) -> int:
        return len(self.folds)

    @property
    def mean(self) -> float:
        return float(np.mean(self.differences))

    @property
    def sd(self) -> float:
        """Sample standard deviation of the per-fold differences (NaN with one fold)."""
        return float(np.std(self.differences, ddof=1)) if self.pairs > 1 else math.nan

    @property
    def effect_dz(self) -> float:
        """Mean / sd of the per-fold differences (NaN when they do not vary)."""
        return self.mean / self.sd if self.sd > 0 else math.nan

    @cached_property
    def test(self) -> SignFlip:
        return SignFlip(self.differences, self.config.confidence)

    @property
    def p_value(self) -> float:
        return self.test.p_value(0.0)

    @property
    def ci(self) -> tuple[float, float]:
        """The test inverted at ``config.confidence``: ``(ci_low, ci_high)``."""
        return self.test.interval()

    @property
    def ci_low(self) -> float:
        return self.ci[0]

    @property
    def ci_high(self) -> float:
        return self.ci[1]

    @property
    def seed_share(self) -> float:
        """Share of var(d) that the seeds' noise explains, clipped to [0, 1]; NaN when unknown."""
        if math.isnan(self.seed_variance) or not self.sd > 0:
            return math.nan
        return min(1.0, self.seed_variance / self.sd ** 2)

    def power(self, mean: float, sign: int) -> float:
        """Probability that the test rejects with the sign ``sign`` when the fold differences are
        normal with ``mean`` and our standard deviation (``power``)."""
        return power(self.pairs, mean, self.sd, sign, self.config)

    def describe(self) -> str:
        """A few lines for a terminal."""
        seeds = (f"{self.seeds[0]}" if self.seeds[0] == self.seeds[1]
                 else f"{self.seeds[0]}-{self.seeds[1]}")
        per_fold = "  ".join(f"{f} {d:+.2f}" for f, d in zip(self.folds, self.differences))
        dropped = ", ".join(f"{f} (no {sides})" for f, sides in self.dropped.items()) or "none"
        low, high = self.ci
        shares = ("unknown with one seed" if math.isnan(self.seed_share) else
                  f"seeds {self.seed_share:.0%}, folds {1 - self.seed_share:.0%}")
        return "\n".join([
            f"{self.contrast} on {self.metric}",
            f"unit of pairing: {self.unit}",
            f"pairs: {self.pairs} folds, {seeds} seed(s) per side and fold; dropped: {dropped}",
            f"per-fold differences: {per_fold}",
            f"mean difference: {self.mean:+.3f} (sd {self.sd:.3f}, d_z {self.effect_dz:+.2f}; "
            f"variance shares: {shares})",
            f"{self.config.confidence:.0%} CI [{low:+.3f}, {high:+.3f}], p = {self.p_value:.4f} "
            f"(smallest attainable {self.test.smallest_p:.4f}): {self.config.method}"])


def _scores(runs: pd.DataFrame) -> list[str]:
    """The metric columns of a per-run table other than per-class scores, in its order."""
    return [column for column in runs.columns
            if column not in KEY_COLUMNS + CONVERGENCE_COLUMNS + ["architecture"]
            and not per_class(column.split("_", 1)[-1])]


def paired(runs: pd.DataFrame, contrast: Contrast, metric: str,
           config: StatsConfig = StatsConfig()) -> PairedResult:
    """Paired statistics of ``contrast`` on ``metric`` over the folds every side ran.

    Args:
        runs: one row per run (``collect.run_rows``): columns ``annotations, direction, variant,
            weighting, seed, fold`` and the metrics.
        contrast: the per-fold quantity, e.g. ``Contrast(ConfigId("APc"), ConfigId("A"))``.
        metric: a metric column, e.g. ``gesture_edit``.
        config: the test's level and the power simulation's settings.

    Raises:
        NotPaired: a side has no run with a value of ``metric``, or the sides share no fold.
        ValueError: ``metric`` is not a column of ``runs``.
    """
    if metric not in runs.columns:
        raise ValueError(f"metric {metric!r} is not in the runs table; known: "
                         f"{', '.join(_scores(runs))} and the per-class scores "
                         "(<task>_<accuracy|precision|recall|f1>_<class>, e.g. "
                         "gesture_accuracy_G2)")
    sides = {side.label: (coef, seed_values(runs, side, metric))
             for side, coef in contrast.terms().items()}
    return paired_sides(contrast.label, metric, sides, config)


def paired_sides(label: str, metric: str, sides: dict[str, tuple[int, dict[str, np.ndarray]]],
                 config: StatsConfig = StatsConfig()) -> PairedResult:
    """Paired statistics of ``sum(coefficient x side)`` per fold over the folds every side has,
    each side averaged over its seeds within a fold: ``paired``'s procedure for sides that need
    not be configurations of one table (e.g. one configuration in two grids, ``execution``).

    Args:
        label: the contrast's name, e.g. ``fused A-fixed - reference A-fixed``.
        metric: the metric the values are of.
        sides: side name -> (coefficient +1 or -1, fold -> the side's values over its seeds).
        config: the test's level and the power simulation's settings.

    Raises:
        NotPaired: the sides share no fold.
    """
    common = sorted(set.intersection(*(set(values) for _, values in sides.values())))
    if not common:
        raise NotPaired(f"{label} on {metric}: the sides share no fold")
    dropped = {fold: ", ".join(name for name, (_, values) in sides.items() if fold not in values)
               for fold in sorted(set().union(*(values for _, values in sides.values()))
                                  - set(common))}
    differences = sum(coef * np.array([values[f].mean() for f in common])
                      for coef, values in sides.values())
    counts = [len(values[f]) for _, values in sides.values() for f in common]
    return PairedResult(
        contrast=label, metric=metric, folds=tuple(common),
        differences=tuple(float(d) for d in differences), dropped=dropped,
        seeds=(min(counts), max(counts)),
        seed_variance=_seed_variance([[values[f] for f in common]
                                      for _, values in sides.values()]),
        config=config)


def _seed_variance(per_side: list[list[np.ndarray]]) -> float:
    """What the seed-to-seed noise of every side adds to the variance of a per-fold difference:
    per side, its within-fold seed variance (pooled over the folds with 2 or more seeds) times the
    mean over folds of 1 / seeds; summed over sides (coefficients are +-1). NaN when a side has
    one seed on every fold."""
    total = 0.0
    for folds in per_side:
        within = [np.var(v, ddof=1) for v in folds if len(v) > 1]
        if not within:
            return math.nan
        total += float(np.mean(within)) * float(np.mean([1 / len(v) for v in folds]))
    return total


def config_labels(runs: pd.DataFrame) -> list[str]:
    """The labels of every configuration in a per-run table, sorted."""
    columns = ["variant", "weighting", "annotations", "direction"]
    columns += ["architecture"] if "architecture" in runs.columns else []
    configs = runs[columns].drop_duplicates()
    return sorted(ConfigId(*c).label for c in configs.itertuples(index=False))


def seed_values(runs: pd.DataFrame, side: ConfigId, metric: str) -> dict[str, np.ndarray]:
    """Fold -> the side's values over its seeds (NaNs left out)."""
    rows = side.select(runs)
    if rows.empty:
        raise NotPaired(f"no finished runs of {side.label}")
    return fold_values(rows, metric, side.label)


def fold_values(rows: pd.DataFrame, metric: str, label: str) -> dict[str, np.ndarray]:
    """Fold -> the values of ``metric`` over the seeds of ``rows``, one side's (columns ``fold``
    and ``metric``; NaNs left out); ``NotPaired`` naming ``label`` when there are none."""
    values = rows[["fold", metric]].dropna() if metric in rows.columns else rows.iloc[:0]
    if values.empty:
        raise NotPaired(f"{label} has no values of {metric}")
    return {str(fold): group[metric].to_numpy(float) for fold, group in values.groupby("fold")}


def power(folds: int, mean: float, sd: float, sign: int,
          config: StatsConfig = StatsConfig()) -> float:
    """Probability that the sign-flip test over ``folds`` normal fold differences with ``mean`` and
    standard deviation ``sd`` rejects "no difference" at ``config``'s level with the sign ``sign``
    (+1: the interval lies above 0; -1: below). NaN when ``sd`` is not positive or unknown.

    The interval of ``mean + sd * z`` is ``mean + sd * interval(z)``, so the power is the share of
    the simulated standard normal ``z`` (``simulated_intervals``) whose interval end lies beyond
    ``-mean / sd``.
    """
    if not sd > 0 or math.isnan(mean):
        return math.nan
    low, high = simulated_intervals(folds, config)
    beyond = low > -mean / sd if sign > 0 else high < -mean / sd
    return float(np.mean(beyond))


def equivalence_power(folds: int, mean: float, sd: float, margin: float,
                      config: StatsConfig = StatsConfig()) -> float:
    """Probability that the interval lies inside ``(-margin, margin)`` when the fold differences
    are normal with ``mean`` and ``sd`` (as ``power``)."""
    if not sd > 0 or math.isnan(mean):
        return math.nan
    low, high = simulated_intervals(folds, config)
    return float(np.mean((mean + sd * low > -margin) & (mean + sd * high < margin)))


@lru_cache(maxsize=8)
def simulated_intervals(folds: int, config: StatsConfig) -> tuple[np.ndarray, np.ndarray]:
    """The exact intervals of ``config.power_samples`` vectors of ``folds`` standard normal
    differences, drawn from ``numpy.random.default_rng(config.power_seed)``: ``(low, high)``,
    ``[power_samples]`` each (infinite where the test can reject nothing)."""
    rng = np.random.default_rng(config.power_seed)
    z = rng.standard_normal((config.power_samples, folds))
    groups = _split_masks(folds).astype(float)                            # [M, n]
    sizes = groups.sum(axis=1)
    needed = SignFlip(np.zeros(folds), config.confidence).needed
    if needed == 0:
        infinite = np.full(config.power_samples, np.inf)
        return -infinite, infinite
    low, high = np.empty(config.power_samples), np.empty(config.power_samples)
    chunk = max(1, 2 ** 19 // len(groups))                              # fits a cache
    for start in range(0, config.power_samples, chunk):
        block = z[start:start + chunk]                                    # [B, n]
        flipped = block @ groups.T / sizes
        others = (block.sum(axis=1, keepdims=True) - block @ groups.T) / (folds - sizes)
        lows, highs = np.minimum(flipped, others), np.maximum(flipped, others)
        low[start:start + chunk] = np.partition(lows, needed - 1, axis=1)[:, needed - 1]
        high[start:start + chunk] = -np.partition(-highs, needed - 1, axis=1)[:, needed - 1]
    return low, high


def holm(p_values: Sequence[float], size: int | None = None) -> np.ndarray:
    """Holm's step-down adjusted p-values (same order as ``p_values``; NaN stays NaN): the i-th
    smallest of the ``m`` tested is ``max_{j <= i} min(1, (size - j + 1) p_(j))``.

    Args:
        p_values: the family's p-values; NaN for a member not tested (yet).
        size: the family's declared size, tested or not; default the number tested. Counting
            the untested members (as if their p were 1) keeps a partial grid from shrinking the
            correction of the members it did test.

    Raises:
        ValueError: ``size`` is smaller than the number of tested members.
    """
    p = np.asarray(p_values, float)
    adjusted = np.full(p.shape, np.nan)
    tested = np.flatnonzero(~np.isnan(p))
    size = len(tested) if size is None else size
    if size < len(tested):
        raise ValueError(f"a family of {size} cannot hold {len(tested)} tested p-values")
    order = tested[np.argsort(p[tested], kind="stable")]
    running = 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (size - rank) * p[index]))
        adjusted[index] = running
    return adjusted
