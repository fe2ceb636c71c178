"""Paired statistics over folds and seeds, and the paper's claims table."""
from __future__ import annotations

import json
from pathlib import Path
import re

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.claims import (CLAIMS, COLUMNS, MIN_PAIRS, VERDICTS, Claim, evaluate,
                                       paper_difference, paper_value, verdict)
from multitask.evidence.claims_table import claims_latex
from multitask.evidence.collect import LOWER_IS_BETTER, METRICS
from multitask.evidence.latex import escape, required_packages
from multitask.evidence.paired import BootstrapConfig, ConfigId, Contrast, NotPaired, paired
from multitask.evidence.cli import main as tables_main

FOLDS = tuple("BCDEFGHI")
A, APC = ConfigId("A"), ConfigId("APc")
FAST = BootstrapConfig(resamples=1000)


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


def test_a_planted_effect_is_covered_and_reproduced():
    rng = np.random.default_rng(1)
    runs = _runs({APC: 2.0, A: 0.0}, rng, seeds=3)
    result = paired(runs, Contrast(APC, A), "gesture_edit")
    assert result.ci_low < 2.0 < result.ci_high
    assert result.ci_low > 0 and result.p_value < 0.05
    assert (result.pairs, result.seeds) == (8, (3, 3))
    claim = Claim("planted", "APc improves", Contrast(APC, A), "gesture_edit", +1)
    assert evaluate(runs, (claim,)).iloc[0]["verdict"] == "reproduced"


def test_without_an_effect_reproduced_is_rare():
    rng = np.random.default_rng(2)
    claim = Claim("null", "APc improves", Contrast(APC, A), "gesture_edit", +1)
    verdicts = [evaluate(_runs({APC: 0.0, A: 0.0}, rng), (claim,), FAST).iloc[0]["verdict"]
                for _ in range(200)]
    assert verdicts.count("reproduced") <= 20
    assert set(verdicts) <= set(VERDICTS)


def test_the_bootstrap_is_seeded_and_deterministic():
    runs = _runs({APC: 1.0, A: 0.0}, np.random.default_rng(3), seeds=2)
    first = paired(runs, Contrast(APC, A), "gesture_edit", FAST)
    again = paired(runs, Contrast(APC, A), "gesture_edit", FAST)
    other = paired(runs, Contrast(APC, A), "gesture_edit", BootstrapConfig(1000, seed=1))
    assert (first.ci_low, first.ci_high) == (again.ci_low, again.ci_high)
    assert (first.ci_low, first.ci_high) != (other.ci_low, other.ci_high)
    assert first.mean == other.mean and first.p_value == other.p_value


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


def test_seeds_are_resampled_within_folds():
    """Every fold's seed means differ by exactly 1, so only resampling the seeds can make the
    interval wider than a point."""
    rows = [{"annotations": "revised", "direction": "bidirectional", "variant": c.variant,
             "weighting": "fixed", "seed": seed, "fold": fold,
             "gesture_edit": 80 + offset + noise}
            for c, offset in ((APC, 1.0), (A, 0.0)) for fold in FOLDS
            for seed, noise in enumerate((-3.0, 0.0, 3.0))]
    runs = pd.DataFrame(rows)
    result = paired(runs, Contrast(APC, A), "gesture_edit", FAST)
    assert result.differences == pytest.approx([1.0] * len(FOLDS))
    assert result.ci_low < 0.5 and result.ci_high > 1.5
    folds_only = paired(runs, Contrast(APC, A), "gesture_edit",
                        BootstrapConfig(1000, resample_seeds=False))
    assert (folds_only.ci_low, folds_only.ci_high) == pytest.approx((1.0, 1.0))


def test_difference_of_differences_is_paired_per_fold():
    configs = {ConfigId("APr", "gradnorm"): 3.0, ConfigId("APr"): 0.0,
               ConfigId("APc", "gradnorm"): 1.0, APC: 0.0}
    runs = _runs(configs, np.random.default_rng(5), seeds=3, noise_sd=0.5)
    contrast = Contrast(*list(configs)[:2], tuple(list(configs)[2:]))
    assert contrast.label == "(APr-gradnorm - APr-fixed) - (APc-gradnorm - APc-fixed)"
    result = paired(runs, contrast, "gesture_edit", FAST)
    assert result.ci_low < 2.0 < result.ci_high and result.ci_low > 0
    means = runs.groupby(["variant", "weighting", "fold"]).gesture_edit.mean()
    expected = [(means["APr", "gradnorm", f] - means["APr", "fixed", f])
                - (means["APc", "gradnorm", f] - means["APc", "fixed", f]) for f in FOLDS]
    assert result.differences == pytest.approx(expected)


def test_a_configuration_against_itself_is_refused():
    with pytest.raises(ValueError, match="itself"):
        Contrast(APC, APC).terms()


def test_wilcoxon_is_exact_and_ignores_zero_differences():
    runs = _runs({APC: 5.0, A: 0.0}, np.random.default_rng(6), noise_sd=0.1)
    assert paired(runs, Contrast(APC, A), "gesture_edit", FAST).p_value == pytest.approx(2 / 2**8)
    tied = runs.copy()
    apc_b = (tied.variant == "APc") & (tied.fold == "B")
    tied.loc[apc_b, "gesture_edit"] = tied[(tied.variant == "A") & (tied.fold == "B")
                                           ].gesture_edit.to_numpy()
    result = paired(tied, Contrast(APC, A), "gesture_edit", FAST)
    assert result.zero_differences == 1 and result.p_value == pytest.approx(2 / 2**7)


@pytest.mark.parametrize("ci, mean, expect, expected", [
    ((0.5, 2.0), 1.0, +1, "reproduced"), ((-0.5, 2.0), 1.0, +1, "consistent"),
    ((-2.0, 0.5), -1.0, +1, "not reproduced"), ((-2.0, -0.5), -1.0, +1, "contradicted"),
    ((-2.0, -0.5), -1.0, -1, "reproduced"), ((0.5, 2.0), 1.0, -1, "contradicted"),
])
def test_sign_verdicts(ci, mean, expect, expected):
    assert verdict(*ci, mean, expect) == expected


@pytest.mark.parametrize("ci, mean, expected", [
    ((-0.5, 0.8), 0.2, "reproduced"), ((-0.5, 1.5), 0.5, "consistent"),
    ((0.5, 2.0), 1.3, "not reproduced"), ((1.2, 2.0), 1.6, "contradicted"),
    ((-3.0, -1.5), -2.0, "contradicted"),
])
def test_equivalence_verdicts_use_the_margin(ci, mean, expected):
    assert verdict(*ci, mean, 0, margin=1.0) == expected


def test_a_claim_needs_a_sign_or_a_margin():
    with pytest.raises(ValueError, match="margin"):
        Claim("bad", "words", Contrast(APC, A), "gesture_accuracy", 0)


def _full_grid(rng: np.random.Generator, seeds: int = 3) -> pd.DataFrame:
    """Every configuration the claims compare, every metric of ``collect.METRICS``, no effects."""
    configs = {c for claim in CLAIMS for c in _configs(claim)}
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
    assert table.p_value.between(0, 1).all()


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
    # Only Table I's APc vs Pc progress accuracy (89.0 / 89.1 against 89.2) disagrees with the
    # paper's words "all evaluation scores improved"; the row says so.
    assert set(against.claim) == {"progress-vs-single:APc-fixed:progress_accuracy",
                                  "progress-vs-single:APc-gradnorm:progress_accuracy"}
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


def test_claims_name_runs_that_had_not_converged():
    runs = _runs({APC: 1.0, A: 0.0}, np.random.default_rng(16))
    runs["converged"] = ~((runs.variant == "A") & runs.fold.isin(["B", "C"]))
    claim = Claim("c", "APc improves", Contrast(APC, A), "gesture_edit", +1)
    assert "runs still converging: A-fixed 2/8" in evaluate(runs, (claim,), FAST).iloc[0].note


def test_claims_latex_is_a_well_formed_booktabs_table():
    table = evaluate(_full_grid(np.random.default_rng(12), seeds=1), config=FAST)
    tex = claims_latex(table, FAST)
    assert tex.startswith("%") and "booktabs" in tex.splitlines()[1]
    assert tex.count("{") == tex.count("}") and r"\resizebox" not in tex
    body = tex.split(r"\midrule")[1].split(r"\bottomrule")[0].splitlines()
    rows = [line for line in body if line.endswith(r"\\") and not line.startswith(r"\multicolumn")]
    assert len(rows) == len(table)
    assert all(line.count(" & ") == 8 for line in rows)
    assert not re.search(r"(?<!\$)-\d", tex)            # minus signs are $-$


def test_claims_latex_writes_numbers_and_quotes_as_the_tables_do():
    table = evaluate(_full_grid(np.random.default_rng(12), seeds=1), config=FAST).iloc[:1].copy()
    table["quote"] = r"50% of G1 & a_b ~ {x}^2 $# \ in words"
    table[["ours_diff", "ci_low", "ci_high", "paper_diff"]] = [-0.04, -1.25, 0.6, float("nan")]
    tex = claims_latex(table, FAST)
    assert escape(table.quote.iloc[0]) in tex
    row = next(line for line in tex.splitlines() if " & " in line and "Comparison" not in line)
    cells = row.removesuffix(r" \\").split(" & ")
    assert cells[3:6] == ["--", "0.0", "[$-$1.2, 0.6]"]
    assert required_packages(tex) == [r"\usepackage{booktabs}"]


def _write_grid(root, runs: pd.DataFrame) -> None:
    """A finished-runs folder tree as ``multitask-grid`` leaves it (metrics only), with the
    grid's record of its runs (grid.json)."""
    paths = []
    for row in runs.itertuples(index=False):
        path = (Path("runs") / row.annotations / row.direction / f"{row.variant}-{row.weighting}"
                / f"seed{row.seed}" / row.fold)
        paths.append(str(path))
        run = root / path
        run.mkdir(parents=True)
        (run / "metrics.json").write_text(json.dumps({"mean": {"gesture": {
            "accuracy": row.gesture_edit, "edit": row.gesture_edit}}}))
        (run / "finished.json").write_text("{}")
    (root / "grid.json").write_text(json.dumps({"runs": paths}))


def test_cli_writes_the_claims_and_compares_two_configurations(tmp_path, capsys):
    _write_grid(tmp_path, _runs({APC: 2.0, A: 0.0}, np.random.default_rng(13), seeds=2))
    assert tables_main([str(tmp_path), "--no-figures"]) == 0
    claims = pd.read_csv(tmp_path / "tables" / "claims.csv")
    assert list(claims.columns) == COLUMNS
    assert claims.set_index("claim").loc["segmental:APc-fixed:gesture_edit", "verdict"] == (
        "reproduced")
    assert (tmp_path / "tables" / "claims.tex").read_text().count(r"\begin{table*}") == 1
    settings = json.loads((tmp_path / "tables" / "claims_config.json").read_text())
    assert settings["bootstrap"]["resamples"] == BootstrapConfig().resamples
    capsys.readouterr()
    assert tables_main([str(tmp_path), "--compare", "APc-fixed", "A", "--metric",
                        "gesture_edit"]) == 0
    out = capsys.readouterr().out
    assert "APc-fixed - A-fixed on gesture_edit" in out and "8 folds, 2 seed(s)" in out


def test_cli_errors_are_one_line_and_exit_2(tmp_path, capsys):
    _write_grid(tmp_path, _runs({A: 0.0}, np.random.default_rng(14), folds=("B", "C")))
    assert tables_main([str(tmp_path), "--compare", "APx-fixed", "A-fixed", "--metric",
                        "gesture_edit"]) == 2
    error = capsys.readouterr().err
    assert "no finished runs of APx-fixed" in error and "holds A-fixed" in error
    assert "Traceback" not in error
    assert tables_main([str(tmp_path), "--compare", "sideways/A-fixed", "A-fixed", "--metric",
                        "gesture_edit"]) == 2
    assert "'sideways'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        tables_main([str(tmp_path), "--compare", "APc-fixed", "A-fixed"])
    assert exit_info.value.code == 2


def test_config_ids_read_the_run_folder_layout():
    assert ConfigId.parse("original/forward/APoc-gradnorm") == ConfigId(
        "APoc", "gradnorm", "original", "forward")
    assert ConfigId.parse("forward/A") == ConfigId("A", direction="forward")
    assert ConfigId.parse("original/APc-fixed").label == "original/APc-fixed"
    with pytest.raises(NotPaired):
        paired(_runs({A: 0.0}, np.random.default_rng(15)), Contrast(APC, A), "gesture_edit")
