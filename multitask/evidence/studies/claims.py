"""The paper's claims as data, each tested on our runs with paired statistics (``paired``).

A claim is one contrast on one metric with the sign the paper asserts (or, for "only marginally",
an equivalence margin). ``evaluate`` gives one row per claim: the paper's own difference (computed
from its tables, ``paper_results``), ours with the exact sign-flip test over folds and the
interval that inverts it (``paired``), and a verdict.

**Families.** The claims of one quoted sentence of the paper form a family (``Claim.family``, the
claim id's prefix); Holm's step-down correction runs within each family over its **declared**
size, the family's claims whether the grid tested them or not (``p_adjusted``; an untested claim
counts as p = 1, so a partial grid cannot shrink the correction of the claims it did test). At ``n`` folds no p-value is below ``2 / 2^n``, so a family of ``m`` claims
cannot reach an adjusted p below ``m * 2 / 2^n`` (``smallest_adjusted_p``).

**Verdicts**, from the adjusted p-value at level ``1 - confidence`` (0.05):

* sign claims (``expect`` +1 / -1): *reproduced* (significant, our mean has the claimed sign;
  *supported* for a conjecture the paper states but never tested, ``Claim.agreed``),
  *contradicted* (significant, the opposite sign), *inconclusive* (not significant);
* equivalence claims (``expect`` 0, ``|difference| <= margin``): the p-value is that of the
  hypothesis the data lean against: with our mean inside the margin, the larger of the test's p at
  ``-margin`` and ``+margin`` (significant = the interval lies inside the margin: *reproduced*);
  outside it, the p at the margin on its side (significant = the interval lies beyond it:
  *contradicted*); otherwise *inconclusive*.

A *reproduced* or *contradicted* verdict implies the unadjusted interval excludes 0 (or the
margin) on that side; the converse fails where the family's correction matters, and such a row is
*inconclusive* with an interval that excludes 0. Each row also says whether the paper's difference
lies inside our interval (``paper_in_ci``), how many folds favour the claim
(``folds_favouring``: the claimed sign, or within the margin), the standardised effect
``effect_dz`` (mean / sd of the fold differences), ``power_at_paper_effect`` (the probability
that the claim's test, before the family's correction, gives the claimed verdict when the fold
differences are normal with the paper's mean difference and our fold-to-fold sd;
``paired.power``) and the seed and fold shares of the fold differences' variance.

A verdict needs at least ``MIN_PAIRS`` paired folds; a claim whose configurations the grid did not
run keeps its row with empty statistics and a note saying what is missing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ..render.tables import PAPER_TABLES
from ..runs.collect import LOWER_IS_BETTER
from ..statistics.paired import (UNIT_OF_PAIRING, ConfigId, Contrast, PairedResult, StatsConfig,
                                 equivalence_power, holm, paired)

VERDICTS = ("reproduced", "supported", "contradicted", "inconclusive")
#: The fewest paired folds at which the two-sided exact sign-flip test can reach p < 0.05
#: (2 / 2^6 = 0.031); with fewer, statistics are reported without a verdict.
MIN_PAIRS = 6
#: "Only marginally": within one percentage point of frame accuracy. The paper calls changes of
#: -0.2 to +0.7 points marginal (Table I) and an edit / F1@10 gain of 0.5 points an improvement.
FRAME_ACCURACY_MARGIN = 1.0
#: Decimals of ``power_at_paper_effect`` in the table: its Monte-Carlo error (at most 0.0005 with
#: the default 10^6 samples) is far below the last one.
POWER_DECIMALS = 2

COLUMNS = ["claim", "family", "paper_diff", "ours_diff", "ci_low", "ci_high", "paper_in_ci",
           "p_value", "p_adjusted", "verdict", "folds_favouring", "effect_dz",
           "power_at_paper_effect", "seed_share", "fold_share", "folds", "seeds", "quote",
           "comparison", "metric", "annotations", "direction", "pairing", "note"]


def smallest_adjusted_p(claims: int, folds: int) -> float:
    """The smallest Holm-adjusted p-value a family of ``claims`` claims can reach with the exact
    sign-flip test over ``folds`` folds: ``claims * 2 / 2^folds``, at most 1."""
    return min(1.0, claims * 2 / 2 ** folds)


@dataclass(frozen=True)
class BestOf:
    """``x`` against the strongest of ``rivals`` on the metric: chosen on our runs for our test,
    in the paper's table for the paper's difference. Beating the strongest rival is the binding
    test of "best". Choosing it on the same runs biases the difference against the claim: a
    *reproduced* verdict is conservative, a *contradicted* one is not."""

    x: ConfigId
    rivals: tuple[ConfigId, ...]


@dataclass(frozen=True)
class Claim:
    """One claim of the paper: ``comparison`` on ``metric`` should be > 0 (``expect`` +1), < 0
    (-1) or within ``[-margin, margin]`` (0)."""

    claim: str                      # id, e.g. "segmental:APc-fixed:gesture_edit"
    quote: str                      # the paper's words, short
    comparison: Contrast | BestOf
    metric: str
    expect: int
    margin: float = 0.0
    note: str = ""                  # what our test or the paper's evidence is, where not obvious
    published: bool = True          # the paper's tables hold this comparison (paper_diff)
    agreed: str = "reproduced"      # the verdict when our test agrees with the claim: a result
    #                                 is "reproduced", a conjecture the paper never tested
    #                                 "supported"

    def __post_init__(self):
        if self.expect not in (-1, 0, 1) or (self.expect == 0) != (self.margin > 0):
            raise ValueError(f"claim {self.claim}: expect must be +1 or -1 without a margin, or "
                             f"0 with one (expect {self.expect}, margin {self.margin})")

    @property
    def family(self) -> str:
        """The id's part before the first colon: the claims of one quoted sentence (of one
        sentence and score for the TCN conjecture, ``TCN_CLAIMS``)."""
        return self.claim.split(":", 1)[0]

    @property
    def direction(self) -> str:
        if self.expect == 0:
            return f"|diff| <= {self.margin:g}"
        better = " (lower is better)" if self.metric in LOWER_IS_BETTER else ""
        return ("> 0" if self.expect > 0 else "< 0") + better


def verdict(p_adjusted: float, mean: float, expect: int, margin: float = 0.0,
            alpha: float = 0.05) -> str:
    """One of ``VERDICTS`` for a tested claim (rules in the module docstring).

    Args:
        p_adjusted: the claim's p-value after its family's correction (``claim_p_value``, then
            ``paired.holm``).
        mean: the mean difference over folds, in the metric's unit (percentage points).
        expect: the claimed sign, +1 or -1, or 0 for an equivalence claim.
        margin: half-width of the equivalence interval (``expect`` 0), same unit; 0 otherwise.
        alpha: the level (1 - confidence).
    """
    if not p_adjusted <= alpha:
        return "inconclusive"
    if expect == 0:
        return "reproduced" if abs(mean) <= margin else "contradicted"
    return "reproduced" if np.sign(mean) == expect else "contradicted"


def claim_p_value(result: PairedResult, expect: int, margin: float = 0.0) -> float:
    """The unadjusted p-value ``verdict`` reads: of "no difference" for a sign claim; for an
    equivalence claim, of the hypothesis our mean leans against (module docstring)."""
    test = result.test
    if expect:
        return test.p_value(0.0)
    if abs(result.mean) <= margin:
        return max(test.p_value(-margin), test.p_value(margin))
    return test.p_value(math.copysign(margin, result.mean))


def evaluate(runs: pd.DataFrame, claims: tuple[Claim, ...] | None = None,
             config: StatsConfig = StatsConfig()) -> pd.DataFrame:
    """The claims table: one row per claim, columns ``COLUMNS``; every number is a function of
    ``runs`` alone (the power column of ``config``'s fixed simulation too).

    Args:
        runs: one row per finished run (``collect.run_rows``).
        claims: the claims to test; default ``CLAIMS``, the paper's.
        config: the test's level and the power simulation's settings.
    """
    claims = CLAIMS if claims is None else claims
    rows = [_evaluate(claim, runs, config) for claim in claims]
    declared = pd.Series([claim.family for claim in claims]).value_counts()
    tested = pd.DataFrame(rows, columns=COLUMNS).dropna(subset="p_value")
    for family, members in tested.groupby("family", sort=False):
        size = int(declared[family])
        adjusted = holm(members.p_value.to_numpy(float), size=size)
        folds = int(members.folds.max())
        floor = smallest_adjusted_p(size, folds)
        for index, p_adjusted in zip(members.index, adjusted):
            claim, row = claims[index], rows[index]
            row["p_adjusted"] = p_adjusted
            if row["folds"] >= MIN_PAIRS:
                found = verdict(p_adjusted, row["ours_diff"], claim.expect, claim.margin,
                                config.alpha)
                row["verdict"] = claim.agreed if found == "reproduced" else found
            notes = [row["note"]]
            if len(members) < size:
                notes.append(f"Holm over the family's {size} claims, of which {len(members)} "
                             "tested (the untested count as p = 1)")
            if floor > config.alpha:
                notes.append(f"its family of {size} claims at {folds} folds cannot reach an "
                             f"adjusted p below {floor:.3f}: inconclusive whatever the data")
            row["note"] = "; ".join(filter(None, notes))
    return pd.DataFrame(rows, columns=COLUMNS).astype({"folds": "Int64", "seeds": "Int64"})


def _evaluate(claim: Claim, runs: pd.DataFrame, config: StatsConfig) -> dict:
    """A claim's row before its family's correction (``p_adjusted``, ``verdict`` empty)."""
    notes = [claim.note] if claim.note else []
    contrast, paper_contrast = _contrasts(claim, runs, notes)
    paper_diff = paper_difference(paper_contrast, claim.metric) if claim.published else None
    if paper_diff is not None and claim.expect and np.sign(paper_diff) != claim.expect:
        notes.append(f"the paper's own table gives {paper_diff:+.1f}, against its words")
    row = {"claim": claim.claim, "family": claim.family, "paper_diff": paper_diff,
           "quote": claim.quote, "comparison": contrast.label, "metric": claim.metric,
           "annotations": " vs ".join(dict.fromkeys(c.annotations for c in contrast.configs)),
           "direction": claim.direction, "pairing": UNIT_OF_PAIRING}
    try:
        result = paired(runs, contrast, claim.metric, config)
    except ValueError as error:             # not run (NotPaired) or metric absent from the grid
        notes.append(f"not tested: {error}")
        return row | {"note": "; ".join(notes)}
    notes += _result_notes(result) + _convergence_notes(runs, contrast)
    low, high = result.ci
    within = (np.abs(result.differences) <= claim.margin if claim.expect == 0
              else np.sign(result.differences) == claim.expect)
    row |= {"ours_diff": result.mean, "ci_low": low, "ci_high": high,
            "p_value": claim_p_value(result, claim.expect, claim.margin),
            "folds_favouring": f"{int(within.sum())}/{result.pairs}",
            "effect_dz": result.effect_dz, "seed_share": result.seed_share,
            "fold_share": 1 - result.seed_share, "folds": result.pairs, "seeds": result.seeds[0]}
    if paper_diff is not None:
        row["paper_in_ci"] = bool(low <= paper_diff <= high)
        row["power_at_paper_effect"] = round(_power(claim, result, paper_diff, config),
                                             POWER_DECIMALS)
    if result.pairs < MIN_PAIRS:
        notes.append(f"no verdict below {MIN_PAIRS} paired folds")
    return row | {"note": "; ".join(notes)}


def _power(claim: Claim, result: PairedResult, paper_diff: float, config: StatsConfig) -> float:
    """The probability of the claimed verdict (before the family's correction) if the fold
    differences were normal with the paper's mean and our sd."""
    if claim.expect == 0:
        return equivalence_power(result.pairs, paper_diff, result.sd, claim.margin, config)
    return result.power(paper_diff, claim.expect)


def _contrasts(claim: Claim, runs: pd.DataFrame, notes: list[str]
               ) -> tuple[Contrast, Contrast | None]:
    """Our contrast and the paper's (they differ only for ``BestOf``, whose strongest rival is
    chosen separately on each side); appends the choice to ``notes``."""
    if isinstance(claim.comparison, Contrast):
        return claim.comparison, claim.comparison
    x, rivals = claim.comparison.x, claim.comparison.rivals
    ours = _strongest(rivals, claim.metric, lambda c: _our_mean(runs, c, claim.metric))
    theirs = _strongest(rivals, claim.metric, lambda c: paper_value(c, claim.metric))
    notes.append(f"against the strongest other of {', '.join(r.label for r in rivals)}: ours "
                 f"{ours.label if ours else 'none run'}, the paper's "
                 f"{theirs.label if theirs else 'none published'} (chosen on the same runs: "
                 "biased against the claim)")
    return Contrast(x, ours or rivals[0]), Contrast(x, theirs) if theirs else None


def _strongest(configs: tuple[ConfigId, ...], metric: str, score) -> ConfigId | None:
    """The config with the best ``score`` (which returns None where it has none)."""
    scored = [(s, c) for c in configs if (s := score(c)) is not None]
    if not scored:
        return None
    pick = min if metric in LOWER_IS_BETTER else max
    return pick(scored, key=lambda pair: pair[0])[1]


def _our_mean(runs: pd.DataFrame, config: ConfigId, metric: str) -> float | None:
    """Mean over folds of the per-fold seed means, None if not run."""
    if metric not in runs.columns:
        return None
    values = config.select(runs)[["fold", metric]].dropna()
    return None if values.empty else float(values.groupby("fold")[metric].mean().mean())


def _result_notes(result: PairedResult) -> list[str]:
    notes = []
    if result.dropped:
        notes.append("folds dropped (not run by every side): "
                     + ", ".join(f"{fold} (no {sides})" for fold, sides in result.dropped.items()))
    if result.seeds[0] != result.seeds[1]:
        notes.append(f"{result.seeds[0]}-{result.seeds[1]} seeds per side and fold")
    return notes


def _convergence_notes(runs: pd.DataFrame, contrast: Contrast) -> list[str]:
    """Which sides have runs whose training loss was still falling, or undecided (``collect``'s
    ``convergence`` column, where the grid records it)."""
    if "convergence" not in runs.columns:
        return []
    notes = []
    for state in ("still falling", "undecided"):
        counts = []
        for side in contrast.configs:
            verdicts = side.select(runs).convergence
            if n := int(verdicts.eq(state).sum()):
                counts.append(f"{side.label} {n}/{len(verdicts)}")
        if counts:
            notes.append(f"runs {state}: {', '.join(counts)}")
    return notes


_PAPER = {(table.annotations, table.direction): table.paper for table in PAPER_TABLES}


def paper_value(config: ConfigId, metric: str) -> float | None:
    """The paper's mean for a configuration and metric (Tables I-III), None where it gives none."""
    published = _PAPER.get((config.annotations, config.direction), {})
    number = published.get(f"{config.variant}-{config.weighting}", {}).get(metric)
    return None if number is None else number[0]


def paper_difference(contrast: Contrast | None, metric: str) -> float | None:
    """``contrast`` on the paper's published means, None if a side is missing; rounded to the
    tables' one decimal."""
    if contrast is None:
        return None
    values = {c: paper_value(c, metric) for c in contrast.terms()}
    if any(v is None for v in values.values()):
        return None
    return round(sum(coef * values[c] for c, coef in contrast.terms().items()), 1)


# --- The paper's claims ---------------------------------------------------------------------

A = ConfigId("A")
MULTITASK = tuple(ConfigId(v, w) for v in ("APr", "APc", "APoc") for w in ("fixed", "gradnorm"))
SEGMENTAL = ("gesture_edit", "gesture_f1@10")
PROGRESS = ("progress_accuracy", "progress_edit", "progress_f1@10")


def _gradnorm_gain_difference(other: str) -> Contrast:
    """APr's GradNorm gain minus ``other``'s: (APr-gradnorm - APr-fixed) - (other-gradnorm -
    other-fixed)."""
    return Contrast(ConfigId("APr", "gradnorm"), ConfigId("APr"),
                    (ConfigId(other, "gradnorm"), ConfigId(other)))


_Q_SEGMENTAL = ("All three multi-task architectures outperform the single-task baseline on the "
                "segmental scores (Edit and F1@10)")
_Q_FRAME = ("the advantage of the proposed method ... mainly affects the segmental scores and only "
            "marginally the framewise evaluation metrics")
_Q_APOC = ("Even if none of the proposed architectures clearly stands out from the others, APoc "
           "generates slightly better results")
_Q_GRADNORM = ("The architecture that benefits the most from multi-task gradient normalization "
               "is APr")
_Q_PROGRESS = ("For APr and APc, but not for APoc, all evaluation scores improved with respect to "
               "their single-task counterparts Pr and Pc")
_Q_LABELS = ("sensitivity of our models to action annotation noise ... This results in "
             "performance degradation with respect to the previous experiments, especially for "
             "APoc")
_Q_DIPIETRO = ("the proposed networks significantly outperform [DiPietro et al.] both in accuracy "
               "and Edit score")
_Q_ONLINE = ("We reached accuracy and Edit score of 82.2 and 76.2 respectively, improving upon the "
             "original single-task baseline")
_PUBLISHED = ("the paper's {side} is DiPietro et al.'s published {model}, not a run of the "
              "authors: its difference is against a published number; ours pairs our own runs")

CLAIMS: tuple[Claim, ...] = (
    *(Claim(f"segmental:{mt.label}:{metric}", _Q_SEGMENTAL, Contrast(mt, A), metric, +1)
      for mt in MULTITASK for metric in SEGMENTAL),
    *(Claim(f"frame-accuracy:{mt.label}:gesture_accuracy", _Q_FRAME, Contrast(mt, A),
            "gesture_accuracy", 0, FRAME_ACCURACY_MARGIN,
            note=f"equivalence within +-{FRAME_ACCURACY_MARGIN:g} point of frame accuracy")
      for mt in MULTITASK),
    *(Claim(f"apoc-best:APoc-gradnorm:{metric}", _Q_APOC,
            BestOf(ConfigId("APoc", "gradnorm"), (A, *MULTITASK[:-1])), metric, +1,
            note="Table I prints APoc (alpha=1.5) in bold for this score")
      for metric in ("gesture_f1@10",)),
    *(Claim(f"gradnorm-apr-most:APr-vs-{other}:{metric}", _Q_GRADNORM,
            _gradnorm_gain_difference(other), metric, +1,
            note="GradNorm gain = alpha=1.5 minus w1=w2=1, paired per fold")
      for other in ("APc", "APoc") for metric in SEGMENTAL),
    *(Claim(f"progress-vs-single:APr-{w}:progress_mae", _Q_PROGRESS,
            Contrast(ConfigId("APr", w), ConfigId("Pr")), "progress_mae", -1)
      for w in ("fixed", "gradnorm")),
    *(Claim(f"progress-vs-single:APc-{w}:{metric}", _Q_PROGRESS,
            Contrast(ConfigId("APc", w), ConfigId("Pc")), metric, +1)
      for w in ("fixed", "gradnorm") for metric in PROGRESS),
    *(Claim(f"progress-vs-single:APoc-{w}:{metric}", _Q_PROGRESS,
            Contrast(ConfigId("APoc", w), ConfigId("Poc")), metric, expect,
            note="'not all scores improved': each metric with the sign of the paper's Table I")
      for w in ("fixed", "gradnorm")
      for metric, expect in zip(PROGRESS, (+1, -1, -1))),
    *(Claim(f"revised-labels:{v}-fixed:{metric}", _Q_LABELS,
            Contrast(ConfigId(v), ConfigId(v, annotations="original")), metric, +1,
            note="Table I against Table II, whose weighting the paper does not state (we take "
                 "w1=w2=1); each side is scored against its own labels")
      for v in ("APc", "APoc") for metric in ("gesture_accuracy", "gesture_edit")),
    *(Claim(f"revised-labels:APoc-more-than-APc:{metric}", _Q_LABELS,
            Contrast(ConfigId("APoc"), ConfigId("APoc", annotations="original"),
                     (ConfigId("APc"), ConfigId("APc", annotations="original"))), metric, +1,
            note="'especially for APoc': APoc's revised-minus-original gain minus APc's, paired "
                 "per fold (w1=w2=1)")
      for metric in ("gesture_accuracy", "gesture_edit")),
    *(Claim(f"vs-dipietro:{v}-fixed:{metric}", _Q_DIPIETRO,
            Contrast(ConfigId(v, annotations="original"), ConfigId("A", annotations="original")),
            metric, +1,
            note=_PUBLISHED.format(side="baseline (Table II, BiLSTM)", model="bidirectional LSTM")
            + "; the paper reports no significance test")
      for v in ("APc", "APoc") for metric in ("gesture_accuracy", "gesture_edit")),
    *(Claim(f"online:APc-fixed:{metric}", _Q_ONLINE,
            Contrast(ConfigId("APc", direction="forward"), ConfigId("A", direction="forward")),
            metric, +1,
            note=_PUBLISHED.format(side="baseline (Table III, LSTM)", model="forward LSTM"))
      for metric in ("gesture_accuracy", "gesture_edit")),
)


# --- The paper's conjecture, on another task -----------------------------------------------

_Q_CONJECTURE = ("We assumed that action-based progress prediction could help to recognize "
                 "surgical gestures in well-structured tasks such as suturing and knot tying")
CONJECTURE_MODELS = tuple(ConfigId(v, w) for v in ("APc", "APoc") for w in ("fixed", "gradnorm"))

#: For a task other than Suturing (``multitask-tables`` picks these for such a grid): does
#: multi-task progress learning improve on model A there too? The paper has no result on any other
#: task, so ``paper_diff`` stays empty and the expected sign is the conjecture's.
CONJECTURE_CLAIMS: tuple[Claim, ...] = (
    *(Claim(f"conjecture:{mt.label}:{metric}", _Q_CONJECTURE, Contrast(mt, A), metric, +1,
            note="the paper's conjecture, untested there: no published difference",
            published=False)
      for mt in CONJECTURE_MODELS for metric in SEGMENTAL),
    *(Claim(f"conjecture-frame-accuracy:{mt.label}:gesture_accuracy", _Q_FRAME, Contrast(mt, A),
            "gesture_accuracy", 0, FRAME_ACCURACY_MARGIN,
            note=f"equivalence within +-{FRAME_ACCURACY_MARGIN:g} point of frame accuracy, as on "
                 "Suturing; no published difference", published=False)
      for mt in CONJECTURE_MODELS),
)


# --- The paper's conjecture, on temporal convolutional backbones ---------------------------

_Q_ARCHITECTURES = ("we suggest the proposed multi-task approach could be applied on top of more "
                    "complex architectures to boost performance")
#: The backbones of the issue's grid (results/tcn/*.toml), as ``pooling.architecture`` names them.
TCN_BACKBONES = ("ed-tcn", "ms-tcn")
#: The progress heads on a TCN: APc with fixed weights, APoc with GradNorm (alpha 1.5).
TCN_HEADS = (ConfigId("APc", "fixed"), ConfigId("APoc", "gradnorm"))

#: "Progress heads help TCN backbones": per backbone, APc (fixed) - A and APoc (GradNorm) - A on
#: accuracy, edit and F1@10, in three declared families, one per score (4 claims each, Holm over
#: the 4): at 8 folds the exact test's smallest p is 2/256, so one family of all 12 could never
#: reach an adjusted p below 0.094, while a family of 4 can reach 0.031 (docs/REPRODUCTION.md,
#: decided before any TCN run). Read from a table of several architectures (``architectures``),
#: each side a configuration of its backbone's grid. The paper never ran a TCN, so there is no
#: published difference; the expected sign is the conjecture's (+): *supported* = Holm-adjusted
#: p <= alpha with a gain, *contradicted* = with a loss, *inconclusive* = neither shown (which
#: is not evidence of no effect).
#: Each score of the claims and its family's name (``tcn-progress-<name>``).
TCN_FAMILY_OF = {"gesture_accuracy": "accuracy", "gesture_edit": "edit", "gesture_f1@10": "f1@10"}
TCN_CLAIMS: tuple[Claim, ...] = tuple(
    Claim(f"tcn-progress-{TCN_FAMILY_OF[metric]}:{backbone}/{heads.label}:{metric}",
          _Q_ARCHITECTURES,
          Contrast(replace(heads, architecture=backbone), replace(A, architecture=backbone)),
          metric, +1, published=False, agreed="supported",
          note="the paper's conjecture, untested there: no published difference; expected > 0")
    for backbone in TCN_BACKBONES for heads in TCN_HEADS for metric in TCN_FAMILY_OF)
