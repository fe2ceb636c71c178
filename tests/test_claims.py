"""Paired statistics over folds and seeds, and the paper's claims table."""
from __future__ import annotations

import itertools
import json
from pathlib import Path
import re

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.render.latex import escape, required_packages
from multitask.evidence.runs.collect import LOWER_IS_BETTER, METRICS
from multitask.evidence.statistics.paired import (ConfigId, Contrast, NotPaired, SignFlip,
                                                  StatsConfig, holm, paired, power)
from multitask.evidence.studies.claims import (CLAIMS, COLUMNS, MIN_PAIRS, VERDICTS, Claim,
                                               evaluate, paper_difference, paper_value,
                                               smallest_adjusted_p, verdict)
from multitask.evidence.studies.claims_table import claims_latex, write_claims
from multitask.grid.spec import RunKey
from tests.fake_grid import write_fake_run

FOLDS = tuple("BCDEFGHI")
A, APC = ConfigId("A"), ConfigId("APc")
FAST = StatsConfig(power_samples=20_000)


def _runs(offsets: dict[ConfigId, float], rng: np.random.Generator, seeds: int = 1,
          folds: tuple[str, ...] = FOLDS, metric: str = "gesture_edit", fold_sd: float = 6.0,
          noise_sd: float = 1.0) -> pd.DataFrame:
    """A per-run table: score = 80 + the fold's difficulty (shared by every configuration) +
    the configuration's offset + run noise."""
    difficulty = dict(zip(folds, rng.normal(0, fold_sd, len(folds))))
    return pd.DataFrame([
        {"annotations": c.annotations, "direction": c.direction, "variant": c.variant,
         "weighting": c.weighting, "seed": seed, "fold": fold,
         metric: 80 + difficulty[fold] + offset + rng.normal(0, noise_sd)}
        for c, offset in offsets.items() for seed in range(seeds) for fold in folds])


def _brute_force_p(differences, d0: float = 0.0) -> float:
    """The sign-flip p-value by its definition: every sign vector, |sum s (d - d0)| >= |sum|."""
    d = np.asarray(differences) - d0
    signs = np.array(list(itertools.product((1, -1), repeat=d.size)))
    return float(np.mean(np.abs(signs @ d) >= abs(d.sum()) - 1e-12))


def test_a_planted_effect_is_found_and_covered():
    rng = np.random.default_rng(1)
    runs = _runs({APC: 2.0, A: 0.0}, rng, seeds=3)
    result = paired(runs, Contrast(APC, A), "gesture_edit", FAST)
    assert result.ci[0] < 2.0 < result.ci[1]
    assert result.ci[0] > 0 and result.p_value == pytest.approx(2 / 2 ** 8)
    assert (result.pairs, result.seeds) == (8, (3, 3))
    claim = Claim("planted", "APc improves", Contrast(APC, A), "gesture_edit", +1)
    row = evaluate(runs, (claim,), FAST).iloc[0]
    assert row.verdict == "reproduced" and row.folds_favouring == "8/8"
    assert row.p_adjusted == row.p_value                 # a family of one


def test_the_test_rejects_a_null_at_its_nominal_rate_and_a_planted_effect_often():
    """Normal fold differences, 8 folds: under the null the exact test rejects in 12 of the 256
    equally likely sign patterns (4.7 %); the interval covers the truth as often as the test
    does not reject it; a planted effect of one sd is found about as often as ``power`` says."""
    rng = np.random.default_rng(2)
    samples = 3000
    null = [SignFlip(rng.normal(0, 3, 8)) for _ in range(samples)]
    rate = np.mean([t.p_value() <= 0.05 for t in null])
    assert abs(rate - 12 / 256) < 4 * np.sqrt(0.047 * 0.953 / samples)
    covered = np.mean([t.interval()[0] <= 0 <= t.interval()[1] for t in null])
    assert covered == pytest.approx(1 - rate)
    planted = [SignFlip(rng.normal(3.0, 3.0, 8)) for _ in range(samples)]
    found = np.mean([t.interval()[0] > 0 for t in planted])
    expected = power(8, 3.0, 3.0, +1, FAST)
    assert abs(found - expected) < 4 * np.sqrt(0.25 / samples + 0.25 / FAST.power_samples)


def test_the_p_value_is_the_exhaustive_sign_flip_and_the_interval_its_inversion():
    rng = np.random.default_rng(3)
    for n in (6, 7, 8):
        for _ in range(40):
            d = rng.normal(1, 2, n)
            test = SignFlip(d)
            for d0 in (0.0, 1.0, float(d.mean()), float(d[0])):
                assert test.p_value(d0) == pytest.approx(_brute_force_p(d, d0))
            low, high = test.interval()
            assert test.p_value(low) > 0.05 and test.p_value(high) > 0.05
            assert test.p_value(low - 1e-9) <= 0.05 and test.p_value(high + 1e-9) <= 0.05
            assert (test.p_value(0.0) <= 0.05) == (not low <= 0 <= high)
    assert SignFlip(rng.normal(0, 1, 5)).interval() == (-np.inf, np.inf)     # 2/32 > 0.05
    assert SignFlip(np.ones(7)).smallest_p == pytest.approx(2 / 2 ** 7)


def test_zero_differences_stay_in_the_test():
    d = np.array([0.0, 1.0, 2.0, 1.5, 0.5, 3.0, 1.0, 2.5])
    assert SignFlip(d).p_value() == pytest.approx(4 / 256) == pytest.approx(_brute_force_p(d))
    assert SignFlip(np.zeros(8)).p_value() == 1.0


def test_holm_matches_a_hand_computation():
    # sorted: 0.005 x4 = 0.02, 0.01 x3 = 0.03, 0.03 x2 = 0.06, 0.04 x1 = 0.04 -> max(0.06, 0.04)
    adjusted = holm([0.01, 0.04, 0.03, np.nan, 0.005])
    assert adjusted[[0, 1, 2, 4]] == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert np.isnan(adjusted[3])
    assert holm([0.5, 0.6]) == pytest.approx([1.0, 1.0])
    assert smallest_adjusted_p(12, 8) == pytest.approx(12 * 2 / 256)
    assert smallest_adjusted_p(6, 8) < 0.05 < smallest_adjusted_p(7, 8)


def test_holm_counts_a_family_s_untested_members():
    # 2 of a declared 6 tested: their correction is the full family's, as if the 4 had p = 1
    adjusted = holm([0.01, np.nan, 0.02, np.nan, np.nan, np.nan], size=6)
    assert adjusted[[0, 2]] == pytest.approx([0.06, 0.1])
    assert holm([0.01, 0.02], size=6) == pytest.approx(holm([0.01, 0.02, 1, 1, 1, 1])[:2])
    with pytest.raises(ValueError, match="family of 1"):
        holm([0.01, 0.02], size=1)


def test_a_partial_grid_does_not_shrink_its_family_s_correction():
    """A family whose configurations a grid ran only in part is corrected over its declared
    size, so the claims it tested are adjusted as in the full family, not as a smaller one."""
    rng = np.random.default_rng(19)
    full = _full_grid(rng)
    family = "frame-accuracy"
    members = [claim for claim in CLAIMS if claim.family == family]
    assert len(members) > 2
    kept = {c for claim in members[:1] for c in _configs(claim)}
    dropped = {c for claim in members[1:] for c in _configs(claim)} - kept
    partial = full[~full.apply(lambda r: ConfigId(r.variant, r.weighting, r.annotations,
                                                  r.direction) in dropped, axis=1)]
    rows = evaluate(partial, config=FAST).set_index("claim")
    tested = rows[(rows.family == family) & rows.p_value.notna()]
    assert 0 < len(tested) < len(members)
    expected = holm(tested.p_value.to_numpy(float), size=len(members))
    assert tested.p_adjusted.to_numpy() == pytest.approx(expected)
    assert (tested.p_adjusted >= np.minimum(1, tested.p_value * len(members)) - 1e-12).all()
    assert tested.note.str.contains(f"family's {len(members)} claims").all()


def test_power_matches_a_simulation_of_the_test():
    """``power`` (one shared simulation of standard normal intervals, shifted and scaled) against
    the test run on fresh normal differences with another seed."""
    rng = np.random.default_rng(4)
    samples = 4000
    for mean, sd, sign in ((1.0, 2.0, +1), (-1.5, 1.0, -1), (0.5, 1.0, -1)):
        simulated = np.mean([
            (lambda t: t.interval()[0] > 0 if sign > 0 else t.interval()[1] < 0)(
                SignFlip(rng.normal(mean, sd, 8))) for _ in range(samples)])
        error = np.sqrt(0.25 / samples + 0.25 / FAST.power_samples)
        assert abs(power(8, mean, sd, sign, FAST) - simulated) < 4 * error
    assert np.isnan(power(8, 1.0, 0.0, +1, FAST))
    assert FAST.power_error == pytest.approx(0.5 / np.sqrt(20_000))


def test_the_claims_are_byte_identical_whatever_the_random_state(tmp_path):
    runs = _full_grid(np.random.default_rng(5), seeds=2)
    written = []
    for state in (0, 12345):
        np.random.seed(state)
        np.random.random(state % 7 + 1)
        out = tmp_path / str(state)
        out.mkdir()
        written.append([path.read_bytes() for path in write_claims(runs, out, FAST)])
    assert written[0] == written[1]


def test_seed_and_fold_variance_shares():
    """Per-fold differences exactly 1 with seed noise of sd 3 around each fold's mean: the seeds
    explain the spread of the fold means; with one seed the split is unknown."""
    rng = np.random.default_rng(6)
    rows = [{"annotations": "revised", "direction": "bidirectional", "variant": c.variant,
             "weighting": "fixed", "seed": seed, "fold": fold,
             "gesture_edit": 80 + offset + rng.normal(0, 3)}
            for c, offset in ((APC, 1.0), (A, 0.0)) for fold in FOLDS for seed in range(3)]
    noise_only = paired(pd.DataFrame(rows), Contrast(APC, A), "gesture_edit", FAST)
    assert noise_only.seed_share > 0.5
    folds_only = _runs({APC: 1.0, A: 0.0}, rng, seeds=3, noise_sd=0.01)
    folds_only.loc[folds_only.variant == "APc", "gesture_edit"] += np.tile(    # seed-major rows
        rng.normal(0, 3, 8), 3)
    assert paired(folds_only, Contrast(APC, A), "gesture_edit", FAST).seed_share < 0.01
    assert np.isnan(paired(_runs({APC: 1.0, A: 0.0}, rng), Contrast(APC, A), "gesture_edit",
                           FAST).seed_share)


def test_only_the_folds_of_both_sides_are_paired():
    runs = _runs({APC: 1.0, A: 0.0}, np.random.default_rng(4))
    runs = runs[~((runs.variant == "A") & runs.fold.isin(["C", "H"]))
                & ~((runs.variant == "APc") & (runs.fold == "E"))]
    result = paired(runs, Contrast(APC, A), "gesture_edit", FAST)
    assert result.folds == ("B", "D", "F", "G", "I")
    assert result.dropped == {"C": "A-fixed", "E": "APc-fixed", "H": "A-fixed"}
    per_fold = runs.groupby(["variant", "fold"]).gesture_edit.mean()
    expected = [per_fold["APc", f] - per_fold["A", f] for f in result.folds]
    assert result.differences == pytest.approx(expected)
    assert "5 folds" in result.describe() and "C (no A-fixed)" in result.describe()


def test_difference_of_differences_is_paired_per_fold():
    configs = {ConfigId("APr", "gradnorm"): 3.0, ConfigId("APr"): 0.0,
               ConfigId("APc", "gradnorm"): 1.0, APC: 0.0}
    runs = _runs(configs, np.random.default_rng(5), seeds=3, noise_sd=0.5)
    contrast = Contrast(*list(configs)[:2], tuple(list(configs)[2:]))
    assert contrast.label == "(APr-gradnorm - APr-fixed) - (APc-gradnorm - APc-fixed)"
    result = paired(runs, contrast, "gesture_edit", FAST)
    assert result.ci[0] < 2.0 < result.ci[1] and result.ci[0] > 0
    means = runs.groupby(["variant", "weighting", "fold"]).gesture_edit.mean()
    expected = [(means["APr", "gradnorm", f] - means["APr", "fixed", f])
                - (means["APc", "gradnorm", f] - means["APc", "fixed", f]) for f in FOLDS]
    assert result.differences == pytest.approx(expected)


def test_a_configuration_against_itself_is_refused():
    with pytest.raises(ValueError, match="itself"):
        Contrast(APC, APC).terms()


@pytest.mark.parametrize("p, mean, expect, expected", [
    (0.01, 1.0, +1, "reproduced"), (0.01, -1.0, +1, "contradicted"),
    (0.2, 1.0, +1, "inconclusive"), (0.05, -1.0, -1, "reproduced"),
    (0.051, -1.0, -1, "inconclusive"), (0.01, 1.0, -1, "contradicted"),
])
def test_sign_verdicts(p, mean, expect, expected):
    assert verdict(p, mean, expect) == expected


@pytest.mark.parametrize("p, mean, expected", [
    (0.01, 0.2, "reproduced"), (0.3, 0.5, "inconclusive"), (0.01, 1.6, "contradicted"),
    (0.01, -2.0, "contradicted"), (0.3, -1.3, "inconclusive"),
])
def test_equivalence_verdicts_use_the_margin(p, mean, expected):
    assert verdict(p, mean, 0, margin=1.0) == expected


def test_an_equivalence_claim_is_reproduced_when_the_interval_lies_inside_the_margin():
    rng = np.random.default_rng(7)
    claim = Claim("flat", "marginal", Contrast(APC, A), "gesture_edit", 0, 1.0)
    tight = evaluate(_runs({APC: 0.1, A: 0.0}, rng, noise_sd=0.2), (claim,), FAST).iloc[0]
    assert -1 < tight.ci_low and tight.ci_high < 1 and tight.verdict == "reproduced"
    far = evaluate(_runs({APC: 3.0, A: 0.0}, rng, noise_sd=0.2), (claim,), FAST).iloc[0]
    assert far.ci_low > 1 and far.verdict == "contradicted"


def test_a_claim_needs_a_sign_or_a_margin():
    with pytest.raises(ValueError, match="margin"):
        Claim("bad", "words", Contrast(APC, A), "gesture_accuracy", 0)


def _full_grid(rng: np.random.Generator, seeds: int = 3) -> pd.DataFrame:
    """Every configuration the claims compare, every metric of ``collect.METRICS``, no effects."""
    configs = sorted({c for claim in CLAIMS for c in _configs(claim)}, key=str)  # hash-free order
    difficulty = rng.normal(0, 5, len(FOLDS))
    return pd.DataFrame([
        {"annotations": c.annotations, "direction": c.direction, "variant": c.variant,
         "weighting": c.weighting, "seed": seed, "fold": fold,
         **{m: 80 + d + rng.normal(0, 1) for m in METRICS}}
        for c in configs for seed in range(seeds) for fold, d in zip(FOLDS, difficulty)])


def _configs(claim: Claim) -> tuple[ConfigId, ...]:
    comparison = claim.comparison
    return comparison.configs if isinstance(comparison, Contrast) else (comparison.x,
                                                                        *comparison.rivals)


def test_the_claims_table_has_the_required_columns_and_rows():
    table = evaluate(_full_grid(np.random.default_rng(7)), config=FAST)
    assert list(table.columns) == COLUMNS
    assert len(table) >= 20 and table.claim.is_unique
    assert set(table.verdict) <= set(VERDICTS)
    assert (table.folds == len(FOLDS)).all() and (table.seeds == 3).all()
    assert (table.ci_low <= table.ours_diff).all() and (table.ours_diff <= table.ci_high).all()
    assert table.p_value.between(0, 1).all() and (table.p_adjusted >= table.p_value).all()
    assert table.folds_favouring.str.fullmatch(r"\d/8").all()
    assert table.power_at_paper_effect.dropna().between(0, 1).all()
    assert (table.paper_in_ci.dropna() == ((table.ci_low <= table.paper_diff)
                                           & (table.paper_diff <= table.ci_high))).all()


def test_families_are_the_quoted_sentences_and_holm_runs_within_each():
    table = evaluate(_full_grid(np.random.default_rng(17)), config=FAST)
    assert (table.groupby("family").quote.nunique() == 1).all()
    assert (table.groupby("quote").family.nunique() == 1).all()
    for _, family in table.groupby("family"):
        assert family.p_adjusted.to_numpy() == pytest.approx(holm(family.p_value.to_numpy()))
        assert family.p_value.notna().all()              # the full grid tests every claim
    # No two claims test the same definition; a best-of claim may still resolve to the contrast
    # of another claim when the data make that rival the strongest.
    assert len({(claim.comparison, claim.metric) for claim in CLAIMS}) == len(CLAIMS)
    especially = table.set_index("claim").loc["revised-labels:APoc-more-than-APc:gesture_edit"]
    assert especially.comparison == ("(APoc-fixed - original/APoc-fixed) - "
                                     "(APc-fixed - original/APc-fixed)")
    assert especially.paper_diff == pytest.approx(1.6)         # (86.2 - 84.5) - (85.4 - 85.3)


def test_the_interval_and_the_test_agree_on_every_claim():
    """For a sign claim the interval excludes 0 exactly when p <= 0.05; for an equivalence claim
    it lies inside the margin exactly when p (of the margins) <= 0.05 and the mean is inside."""
    rng = np.random.default_rng(18)
    runs = _full_grid(rng)
    for c in {c for claim in CLAIMS for c in _configs(claim)} - {A}:     # some real effects
        runs.loc[(runs.variant == c.variant) & (runs.weighting == c.weighting),
                 METRICS] += rng.normal(0, 1.5)
    table = evaluate(runs, config=FAST)
    sign = table[~table.direction.str.startswith("|")]
    excludes = (sign.ci_low > 0) | (sign.ci_high < 0)
    assert ((sign.p_value <= 0.05) == excludes).all() and excludes.any()
    equivalence = table[table.direction.str.startswith("|")]
    inside = (equivalence.ci_low > -1) & (equivalence.ci_high < 1)
    mean_inside = equivalence.ours_diff.abs() <= 1
    assert ((equivalence.p_value <= 0.05) & mean_inside == inside).all()
    assert (table[table.verdict != "inconclusive"].p_value <= 0.05).all()


def test_claims_the_grid_did_not_run_are_listed_with_a_note():
    runs = _runs({APC: 1.0, A: 0.0}, np.random.default_rng(8), folds=("B", "C"))
    table = evaluate(runs, config=FAST)
    assert len(table) == len(CLAIMS)
    untested = table[table.ours_diff.isna()]
    assert len(untested) > 0 and untested.verdict.isna().all()
    assert untested.note.str.contains("not tested").all()
    tested = table[table.ours_diff.notna()]
    assert set(tested.metric) == {"gesture_edit"} and (tested.folds == 2).all()
    assert tested.verdict.isna().all()                  # 2 folds < MIN_PAIRS
    assert tested.note.str.contains(f"no verdict below {MIN_PAIRS}").all()


def test_paper_differences_come_from_its_tables_with_the_claimed_sign():
    rows = {claim.claim: claim for claim in CLAIMS}
    edit = rows["segmental:APoc-gradnorm:gesture_edit"]
    assert paper_difference(edit.comparison, edit.metric) == pytest.approx(
        paper_value(ConfigId("APoc", "gradnorm"), "gesture_edit")
        - paper_value(A, "gesture_edit"))
    table = evaluate(_full_grid(np.random.default_rng(9), seeds=1), config=FAST)
    signed = table[table.paper_diff.notna() & ~table.direction.str.startswith("|")]
    expect = np.where(signed.direction.str.startswith(">"), 1, -1)
    against = signed[np.sign(signed.paper_diff) != expect]
    # Table I's APc vs Pc progress accuracy (89.0 / 89.1 against 89.2) disagrees with the paper's
    # words "all evaluation scores improved", and "especially for APoc" has no accuracy gap in its
    # Tables I-II ((85.5 - 85.3) - (85.7 - 85.5) = 0.0); the rows say so.
    assert set(against.claim) == {"progress-vs-single:APc-fixed:progress_accuracy",
                                  "progress-vs-single:APc-gradnorm:progress_accuracy",
                                  "revised-labels:APoc-more-than-APc:gesture_accuracy"}
    assert against.note.str.contains("against its words").all()
    mae = table[table.metric == "progress_mae"]
    assert "progress_mae" in LOWER_IS_BETTER
    assert mae.direction.str.contains("lower is better").all()


def test_claims_with_a_published_side_say_so():
    table = evaluate(_full_grid(np.random.default_rng(10), seeds=1), config=FAST)
    published = table[table.claim.str.startswith(("vs-dipietro", "online"))]
    assert len(published) == 6 and published.note.str.contains("published").all()


def test_best_of_compares_with_our_strongest_other_model():
    runs = _full_grid(np.random.default_rng(11), seeds=1)
    runs.loc[(runs.variant == "APc") & (runs.weighting == "fixed"), "gesture_f1@10"] += 5
    row = evaluate(runs, config=FAST).set_index("claim").loc[
        "apoc-best:APoc-gradnorm:gesture_f1@10"]
    assert row.comparison == "APoc-gradnorm - APc-fixed"
    assert row.verdict == "contradicted"
    assert "ours APc-fixed, the paper's APoc-fixed" in row.note


def test_claims_name_runs_still_falling_or_undecided():
    runs = _runs({APC: 1.0, A: 0.0}, np.random.default_rng(16))
    runs["convergence"] = np.where((runs.variant == "A") & runs.fold.isin(["B", "C"]),
                                   "still falling", "converged")
    runs.loc[(runs.variant == "APc") & (runs.fold == "D"), "convergence"] = "undecided"
    claim = Claim("c", "APc improves", Contrast(APC, A), "gesture_edit", +1)
    note = evaluate(runs, (claim,), FAST).iloc[0].note
    assert "runs still falling: A-fixed 2/8" in note and "runs undecided: APc-fixed 1/8" in note


def test_claims_latex_is_a_well_formed_booktabs_table():
    table = evaluate(_full_grid(np.random.default_rng(12), seeds=1), config=FAST)
    tex = claims_latex(table, FAST)
    assert tex.startswith("%") and "booktabs" in tex.splitlines()[1]
    assert tex.count("{") == tex.count("}") and r"\resizebox" not in tex
    body = tex.split(r"\midrule")[1].split(r"\bottomrule")[0].splitlines()
    rows = [line for line in body if line.endswith(r"\\") and not line.startswith(r"\multicolumn")]
    floats = tex.count(r"\begin{table*}")
    assert floats == 2 and tex.count(r"\label{tab:claims}") == 1
    rows = [line for part in tex.split(r"\midrule")[1:]
            for line in part.split(r"\bottomrule")[0].splitlines()
            if line.endswith(r"\\") and not line.startswith(r"\multicolumn")]
    assert len(rows) == len(table)
    assert all(line.count(" & ") == 10 for line in rows)
    assert not re.search(r"(?<!\$)-\d", tex)            # minus signs are $-$
    assert " A Edit" not in tex and " & Edit & " in tex and " & Progress MAE & " in tex


def test_claims_latex_writes_numbers_and_quotes_as_the_tables_do():
    table = evaluate(_full_grid(np.random.default_rng(12), seeds=1), config=FAST).iloc[:1].copy()
    table["quote"] = r"50% of G1 & a_b ~ {x}^2 $# \ in words"
    table[["ours_diff", "ci_low", "ci_high", "paper_diff"]] = [-0.004, -1.25, 0.6, float("nan")]
    table["paper_in_ci"] = None
    tex = claims_latex(table, FAST, budget="Models: my_pkg.enc:Enc encoder, feature_set chosen")
    assert escape(table.quote.iloc[0]) in tex
    assert r"Models: my\_pkg.enc:Enc encoder, feature\_set chosen" in tex   # the caption's too
    row = next(line for line in tex.splitlines() if " & " in line and "Comparison" not in line)
    cells = row.removesuffix(r" \\").split(" & ")
    assert cells[3:6] == ["--", "0.00", "[$-$1.25, $+$0.60]"]
    table[["ci_low", "ci_high", "paper_diff", "paper_in_ci"]] = [0.0004, 0.998, 3.0, False]
    table["direction"] = "|diff| <= 1"
    cells = next(line for line in claims_latex(table, FAST).splitlines()
                 if " & " in line and "Comparison" not in line).split(" & ")
    assert cells[3] == r"$+$3.0$^\ast$"                    # the paper's outside our interval
    assert cells[5] == "[$+$0.0004, $+$0.998]"              # never printed as 0 or the margin
    assert required_packages(tex) == [r"\usepackage{booktabs}"]


def _write_grid(root, runs: pd.DataFrame) -> None:
    """A finished-runs folder tree as ``multitask-grid`` leaves it (config and metrics only),
    with the grid's record of its runs (grid.json)."""
    paths = []
    for row in runs.itertuples(index=False):
        path = (Path("runs") / row.annotations / row.direction / f"{row.variant}-{row.weighting}"
                / f"seed{row.seed}" / row.fold)
        paths.append(str(path))
        key = RunKey(row.annotations, row.direction, row.variant, row.weighting, row.seed,
                     row.fold)
        write_fake_run(root / path, key, {"gesture": {"accuracy": row.gesture_edit,
                                                     "edit": row.gesture_edit}})
    (root / "grid.json").write_text(json.dumps({"runs": paths}))


@pytest.mark.slow
def test_cli_writes_the_claims_and_compares_two_configurations(tmp_path, capsys):
    _write_grid(tmp_path, _runs({APC: 2.0, A: 0.0}, np.random.default_rng(13), seeds=2))
    assert tables_main(["paper", str(tmp_path), "--no-figures"]) == 0
    claims = pd.read_csv(tmp_path / "tables" / "claims.csv")
    assert list(claims.columns) == COLUMNS
    row = claims.set_index("claim").loc["segmental:APc-fixed:gesture_edit"]
    size = sum(claim.family == "segmental" for claim in CLAIMS)
    # The planted gain is found (every fold), but the grid ran 1 of the family's configurations:
    # the correction is still over the whole declared family, which 8 folds cannot pass.
    assert row.p_value == pytest.approx(2 / 2 ** 8, abs=1e-4) and row.ci_low > 0
    assert row.p_adjusted == pytest.approx(min(1.0, size * 2 / 2 ** 8), abs=1e-4)
    assert row.verdict == "inconclusive" and f"family's {size} claims" in row.note
    assert (tmp_path / "tables" / "claims.tex").read_text().count(r"\begin{table*}") >= 1
    settings = json.loads((tmp_path / "tables" / "claims_config.json").read_text())
    assert settings["statistics"] == {"confidence": 0.95, "power_samples": 1_000_000,
                                      "power_seed": 0}
    capsys.readouterr()
    assert tables_main(["pair", str(tmp_path), "APc-fixed", "A", "--metric",
                        "gesture_edit"]) == 0
    out = capsys.readouterr().out
    assert "APc-fixed - A-fixed on gesture_edit" in out and "8 folds, 2 seed(s)" in out


def test_cli_errors_are_one_line_and_exit_2(tmp_path, capsys):
    _write_grid(tmp_path, _runs({A: 0.0}, np.random.default_rng(14), folds=("B", "C")))
    assert tables_main(["pair", str(tmp_path), "APx-fixed", "A-fixed", "--metric",
                        "gesture_edit"]) == 2
    error = capsys.readouterr().err
    assert "no finished runs of APx-fixed" in error and "holds A-fixed" in error
    assert "Traceback" not in error
    assert tables_main(["pair", str(tmp_path), "sideways/A-fixed", "A-fixed", "--metric",
                        "gesture_edit"]) == 2
    assert "'sideways'" in capsys.readouterr().err
    assert tables_main(["pair", str(tmp_path), "A-fixed", "A-fixed", "--metric", "f1"]) == 2
    error = capsys.readouterr().err
    assert "known: gesture_accuracy, gesture_edit and the per-class scores" in error
    assert len(error.splitlines()) == 1                  # every score the table has, one line
    with pytest.raises(SystemExit) as exit_info:
        tables_main(["pair", str(tmp_path), "APc-fixed", "A-fixed"])
    assert exit_info.value.code == 2


def test_config_ids_read_the_run_folder_layout():
    assert ConfigId.parse("original/forward/APoc-gradnorm") == ConfigId(
        "APoc", "gradnorm", "original", "forward")
    assert ConfigId.parse("forward/A") == ConfigId("A", direction="forward")
    assert ConfigId.parse("original/APc-fixed").label == "original/APc-fixed"
    with pytest.raises(NotPaired):
        paired(_runs({A: 0.0}, np.random.default_rng(15)), Contrast(APC, A), "gesture_edit")
