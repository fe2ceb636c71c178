"""Paired statistics over LOUO folds: is configuration X better than Y on a metric, and by how much?

The unit of pairing is the LOUO fold (one test user): every configuration is evaluated on the same
held-out surgeon, so fold-to-fold differences in difficulty (the 5-8 point standard deviations of
the paper's tables) cancel in the per-fold difference. Within a fold each side is the mean over
its seeds; seeds are not paired (seed k of X and seed k of Y share nothing but a number).

For a contrast (``X - Y``, or a difference of differences ``(X1 - Y1) - (X2 - Y2)``) on a metric:

* the per-fold differences on the folds every side ran (the others are dropped and named), and
  their mean;
* a 95 % confidence interval from a two-level bootstrap: resample folds with replacement, then,
  within each drawn fold, each side's seeds with replacement (a no-op with one seed). The interval
  is the *expanded percentile* interval (Hesterberg 2015, "What teachers should know about the
  bootstrap", The American Statistician 69(4)): the percentile interval at the widened level
  ``alpha' = 2 Phi(-sqrt(n / (n - 1)) t_{1 - alpha/2, n - 1})`` (0.0115 for n = 8 folds instead
  of 0.05). The plain percentile interval of a mean of 8 values is too narrow (simulated coverage
  88 % for a nominal 95 %; expanded: 93-95 %); BCa does not repair that narrowness and its
  jackknife acceleration is not defined for the two-level resampling. Resampling the seeds as
  well counts their noise twice (it is already in the spread of the per-fold differences; Ren
  et al. 2010, J. Appl. Stat. 37(9)), so with several seeds the interval is conservative
  (simulated coverage 97-100 %); ``BootstrapConfig(resample_seeds=False)`` resamples folds only
  (93-94 %). A seeded ``numpy.random.Generator`` per comparison makes every interval
  deterministic and independent of the order in which comparisons are made;
* the two-sided Wilcoxon signed-rank p-value of the per-fold differences
  (``scipy.stats.wilcoxon``): exact for n <= 50 distinct differences, and an exhaustive
  permutation over all 2^n sign flips when there are ties (n <= 13, so always for 8 folds). Zero
  differences are discarded (``zero_method="wilcox"``, Wilcoxon's convention: a fold on which both
  sides score the same says nothing about the sign); their number is reported, and a contrast
  whose differences are all zero has p = 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from jigsaws_tools.annotations import ANNOTATION_VERSIONS

from .collect import METRICS
from ..grid.spec import DIRECTIONS

UNIT_OF_PAIRING = "LOUO fold (test user); each side averaged over its seeds within the fold"


@dataclass(frozen=True)
class ConfigId:
    """One configuration of the grid: its runs
    ``runs/<annotations>/<direction>/<variant>-<weighting>/seed<k>/<fold>``."""

    variant: str
    weighting: str = "fixed"
    annotations: str = "revised"
    direction: str = "bidirectional"

    @classmethod
    def parse(cls, text: str) -> ConfigId:
        """``[annotations/][direction/]<variant>-<weighting>`` as in the grid's run folders, e.g.
        ``APc-fixed``, ``original/APoc-gradnorm``, ``revised/forward/A-fixed``; the weighting
        may be left out (``fixed``). Unnamed parts default to revised labels, bidirectional."""
        *prefix, config = text.split("/")
        variant, _, weighting = config.partition("-")
        values = {"variant": variant, "weighting": weighting or "fixed"}
        for part in prefix:
            if part in ANNOTATION_VERSIONS:
                values["annotations"] = part
            elif part in DIRECTIONS:
                values["direction"] = part
            else:
                raise ValueError(f"configuration {text!r}: {part!r} is neither an annotation "
                                 f"version ({', '.join(ANNOTATION_VERSIONS)}) nor a direction "
                                 f"({', '.join(DIRECTIONS)})")
        if not variant or len(prefix) > 2:
            raise ValueError(f"configuration {text!r}: expected "
                             "[annotations/][direction/]<variant>-<weighting>, e.g. APc-fixed")
        return cls(**values)

    @property
    def label(self) -> str:
        """``<variant>-<weighting>``, prefixed by the labels and direction where they are not the
        defaults (revised, bidirectional)."""
        prefix = [p for p, default in ((self.annotations, "revised"),
                                       (self.direction, "bidirectional")) if p != default]
        return "/".join([*prefix, f"{self.variant}-{self.weighting}"])

    def select(self, runs: pd.DataFrame) -> pd.DataFrame:
        """This configuration's rows of a per-run table (``collect.run_rows``)."""
        return runs[(runs.annotations == self.annotations) & (runs.direction == self.direction)
                    & (runs.variant == self.variant) & (runs.weighting == self.weighting)]


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
class BootstrapConfig:
    """The confidence interval's settings (every comparison draws from a fresh generator seeded
    with ``seed``)."""

    resamples: int = 20_000
    confidence: float = 0.95
    seed: int = 0
    resample_seeds: bool = True     # False: folds only, each fold's seed means kept as they are

    @property
    def method(self) -> str:
        levels = "folds, then seeds within folds" if self.resample_seeds else "folds"
        return f"expanded percentile bootstrap (Hesterberg 2015) over {levels}"

    def __post_init__(self):
        if self.resamples < 100:
            raise ValueError(f"resamples must be >= 100 (value: {self.resamples})")
        if not 0 < self.confidence < 1:
            raise ValueError(f"confidence must be in (0, 1) (value: {self.confidence})")


class NotPaired(ValueError):
    """The runs hold no fold on which every side of a contrast has a value."""


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
    mean: float
    ci_low: float                       # NaN with fewer than 2 pairs
    ci_high: float
    p_value: float                      # two-sided Wilcoxon signed-rank over the folds
    zero_differences: int               # discarded by the Wilcoxon test
    bootstrap: BootstrapConfig
    unit: str = UNIT_OF_PAIRING

    @property
    def pairs(self) -> int:
        return len(self.folds)

    def describe(self) -> str:
        """A few lines for a terminal."""
        seeds = (f"{self.seeds[0]}" if self.seeds[0] == self.seeds[1]
                 else f"{self.seeds[0]}-{self.seeds[1]}")
        per_fold = "  ".join(f"{f} {d:+.2f}" for f, d in zip(self.folds, self.differences))
        dropped = ", ".join(f"{f} (no {sides})" for f, sides in self.dropped.items()) or "none"
        level = f"{self.bootstrap.confidence:.0%}"
        ci = (f"{level} CI [{self.ci_low:+.2f}, {self.ci_high:+.2f}] ({self.bootstrap.method}; "
              f"{self.bootstrap.resamples} resamples, seed {self.bootstrap.seed})"
              if self.pairs > 1 else "no CI from one fold")
        return "\n".join([
            f"{self.contrast} on {self.metric}",
            f"unit of pairing: {self.unit}",
            f"pairs: {self.pairs} folds, {seeds} seed(s) per side and fold; dropped: {dropped}",
            f"per-fold differences: {per_fold}",
            f"mean difference: {self.mean:+.2f}, {ci}",
            (f"Wilcoxon signed-rank, two-sided: p = {self.p_value:.3g} "
             f"({self.zero_differences} zero difference(s) discarded)")])


def paired(runs: pd.DataFrame, contrast: Contrast, metric: str,
           config: BootstrapConfig = BootstrapConfig()) -> PairedResult:
    """Paired statistics of ``contrast`` on ``metric`` over the folds every side ran.

    Args:
        runs: one row per run (``collect.run_rows``): columns ``annotations, direction, variant,
            weighting, seed, fold`` and the metrics.
        contrast: the per-fold quantity, e.g. ``Contrast(ConfigId("APc"), ConfigId("A"))``.
        metric: a metric column, e.g. ``gesture_edit``.
        config: bootstrap settings.

    Raises:
        NotPaired: a side has no run with a value of ``metric``, or the sides share no fold.
        ValueError: ``metric`` is not a column of ``runs``.
    """
    if metric not in runs.columns:
        known = [m for m in METRICS if m in runs.columns]
        raise ValueError(f"metric {metric!r} is not in the runs table; known: {', '.join(known)}")
    terms = contrast.terms()
    sides = {side: _seed_values(runs, side, metric) for side in terms}
    common = sorted(set.intersection(*(set(values) for values in sides.values())))
    if not common:
        raise NotPaired(f"{contrast.label} on {metric}: the sides share no fold")
    dropped = {fold: ", ".join(side.label for side, values in sides.items() if fold not in values)
               for fold in sorted(set().union(*sides.values()) - set(common))}
    padded = {side: _padded([values[f] for f in common]) for side, values in sides.items()}
    differences = sum(coef * _fold_means(*padded[side]) for side, coef in terms.items())
    counts = np.concatenate([padded[side][1] for side in terms])
    low, high = _bootstrap_ci(padded, terms, config)
    return PairedResult(
        contrast=contrast.label, metric=metric, folds=tuple(common),
        differences=tuple(float(d) for d in differences), dropped=dropped,
        seeds=(int(counts.min()), int(counts.max())), mean=float(differences.mean()),
        ci_low=low, ci_high=high, p_value=_wilcoxon(differences),
        zero_differences=int(np.sum(differences == 0)), bootstrap=config)


def config_labels(runs: pd.DataFrame) -> list[str]:
    """The labels of every configuration in a per-run table, sorted."""
    configs = runs[["variant", "weighting", "annotations", "direction"]].drop_duplicates()
    return sorted(ConfigId(*c).label for c in configs.itertuples(index=False))


def _seed_values(runs: pd.DataFrame, side: ConfigId, metric: str) -> dict[str, np.ndarray]:
    """Fold -> the side's values over its seeds (NaNs left out)."""
    rows = side.select(runs)
    if rows.empty:
        raise NotPaired(f"no finished runs of {side.label}")
    values = rows[["fold", metric]].dropna()
    if values.empty:
        raise NotPaired(f"{side.label} has no values of {metric}")
    return {str(fold): group[metric].to_numpy(float) for fold, group in values.groupby("fold")}


def _padded(per_fold: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Ragged per-fold seed values as ``[folds, max seeds]`` (NaN-padded) and the counts
    ``[folds]``."""
    counts = np.array([len(v) for v in per_fold])
    values = np.full((len(per_fold), counts.max()), np.nan)
    for i, v in enumerate(per_fold):
        values[i, :len(v)] = v
    return values, counts


def _fold_means(values: np.ndarray, counts: np.ndarray) -> np.ndarray:
    return np.nansum(values, axis=-1) / counts


def _bootstrap_ci(padded: dict[ConfigId, tuple[np.ndarray, np.ndarray]],
                  terms: dict[ConfigId, int], config: BootstrapConfig) -> tuple[float, float]:
    """Expanded percentile interval of the mean per-fold contrast; folds resampled, then (unless
    ``config.resample_seeds`` is off) each side's seeds within every drawn fold."""
    n = next(iter(padded.values()))[1].size
    if n < 2:
        return float("nan"), float("nan")
    rng = np.random.default_rng(config.seed)
    folds = rng.integers(0, n, size=(config.resamples, n))               # [B, n]
    total = np.zeros((config.resamples, n))
    for side, coef in terms.items():
        values, counts = padded[side]
        if not config.resample_seeds:
            total += coef * _fold_means(values, counts)[folds]
            continue
        drawn_counts = counts[folds]                                     # [B, n]
        slots = np.arange(values.shape[1])                              # [S]
        picks = (rng.random((*folds.shape, slots.size)) * drawn_counts[..., None]).astype(int)
        drawn = values[folds[..., None], picks]                          # [B, n, S]
        used = slots < drawn_counts[..., None]
        total += coef * np.where(used, drawn, 0.0).sum(axis=-1) / drawn_counts
    means = total.mean(axis=1)                                           # [B]
    alpha = _expanded_alpha(1 - config.confidence, n)
    low, high = np.quantile(means, [alpha / 2, 1 - alpha / 2])
    return float(low), float(high)


def _expanded_alpha(alpha: float, n: int) -> float:
    """Hesterberg's widened level for the percentile interval of a mean of ``n`` values."""
    return float(2 * stats.norm.cdf(-np.sqrt(n / (n - 1)) * stats.t.ppf(1 - alpha / 2, n - 1)))


def _wilcoxon(differences: np.ndarray) -> float:
    if not np.any(differences):
        return 1.0
    return float(stats.wilcoxon(differences, zero_method="wilcox", alternative="two-sided",
                                method="auto").pvalue)
