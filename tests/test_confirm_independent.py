"""An independent re-implementation of ``results/confirm/PLAN.md``, checked against
``multitask-tables confirm`` on fake grids with chosen scores.

Nothing here imports ``multitask.evidence.statistics.paired``: the sign vectors are enumerated
one by one (``itertools.product``), the p-value is counted from PLAN.md's definition (the share
of the 2^8 sign vectors whose flipped sum is at least the observed sum in absolute value), and
the 95 % interval is found by bisection on that p-value, not from subset means. The plan read is
the committed ``results/confirm/plan.toml`` itself, in a copy of the repository's layout."""
from __future__ import annotations

import itertools
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.grid.spec import Experiment
from tests.fake_grid import FOLDS, write_fake_grid

PLAN = Path(__file__).resolve().parents[1] / "results" / "confirm" / "plan.toml"
METRICS = ("gesture_edit", "gesture_f1@10", "gesture_accuracy")
A, APOC, APC = "A-fixed", "APoc-gradnorm", "APc-fixed"
WIDE_SEEDS, NARROW_SEEDS = (0, 1, 2), (1, 2, 3, 4, 5)
NARROW_EXPERIMENTS = (Experiment(("A",)), Experiment(("APoc",), ("gradnorm",)))
ALPHA = 0.05
TOLERANCE = 1e-9
#: How close two sums of fold differences must be to count as a tie (float rounding only).
TIE = 1e-12
#: Each seed's offset from its fold's mean: zero sum, so the mean over seeds is exact in floats.
OFFSETS = {3: (-1.0, 0.0, 1.0), 5: (-2.0, -1.0, 0.0, 1.0, 2.0)}
#: Planned families: (part, family, role, [(x, y, metric, paper gain)]) as PLAN.md states them.
FAMILIES = [
    ("paper-width", "primary-1024", "primary",
     [(APOC, A, "gesture_edit", 3.0), (APC, A, "gesture_edit", 2.3)]),
    ("paper-width", "secondary-1024", "secondary",
     [(APOC, A, "gesture_f1@10", 2.2), (APC, A, "gesture_f1@10", 1.6),
      (APOC, A, "gesture_accuracy", 0.7), (APC, A, "gesture_accuracy", 0.4)]),
    ("replication-512", "replication-512", "primary", [(APOC, A, "gesture_edit", 3.0)]),
    ("replication-512", "secondary-512", "secondary",
     [(APOC, A, "gesture_f1@10", 2.2), (APOC, A, "gesture_accuracy", 0.7)]),
]


# ---------------------------------------------------------------- the reference implementation

#: Every sign vector over 8 folds, one per row: [256, 8].
SIGNS = np.array(list(itertools.product((1.0, -1.0), repeat=len(FOLDS))))


def sign_flip_p(d: np.ndarray, d0: float = 0.0) -> float:
    """Share of the 2^8 sign vectors s with |sum s (d - d0)| >= |sum (d - d0)| (ties count)."""
    centred = np.asarray(d, float) - d0
    return float(np.mean(np.abs(SIGNS @ centred) >= abs(centred.sum()) - TIE))


def interval_end(d: np.ndarray, side: int) -> float:
    """The end (side -1: lower, +1: upper) of the set of d0 with p(d0) > ALPHA, by bisection
    between the mean (p = 1) and a point far out (rejected)."""
    inside = float(np.mean(d))
    outside = inside + side * (10 * (np.ptp(d) + 1))
    assert sign_flip_p(d, outside) <= ALPHA < sign_flip_p(d, inside)
    for _ in range(200):
        middle = (inside + outside) / 2
        if middle in (inside, outside):
            break
        if sign_flip_p(d, middle) > ALPHA:
            inside = middle
        else:
            outside = middle
    return inside


def holm(p: list[float]) -> list[float]:
    m = len(p)
    order = sorted(range(m), key=lambda i: p[i])
    adjusted, running = [0.0] * m, 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        adjusted[i] = running
    return adjusted


def two_decimals_below(value: float, gain: float) -> bool:
    """PLAN.md: the paper's gain (its published digit) against our interval end, two decimals."""
    return float(f"{value:.2f}") < gain


def expected_rows(scores: dict, part: str, seeds: tuple[int, ...]) -> pd.DataFrame:
    """Every row PLAN.md asks of ``part``: the planned test (with Holm, the rule-out and the
    outcome for primaries), the sensitivity seeds (part 1) and each seed alone."""
    analyses = {"planned": seeds}
    if part == "paper-width":
        analyses["sensitivity"] = (1, 2)
    analyses |= {f"seed {s}": (s,) for s in seeds}
    rows = []
    for analysis, chosen in analyses.items():
        for name, family, role, endpoints in FAMILIES:
            if name != part:
                continue
            found = []
            for x, y, metric, gain in endpoints:
                d = np.array([np.mean([scores[x, s, f][metric] for s in chosen])
                              - np.mean([scores[y, s, f][metric] for s in chosen])
                              for f in FOLDS])
                found.append((x, y, metric, gain, d, sign_flip_p(d)))
            adjusted = holm([p for *_, p in found])
            for (x, y, metric, gain, d, p), p_holm in zip(found, adjusted):
                low, high = interval_end(d, -1), interval_end(d, +1)
                row = {"part": part, "family": family, "analysis": analysis,
                       "comparison": f"{x} - {y}", "metric": metric, "diff": float(np.mean(d)),
                       "ci_low": low, "ci_high": high, "p_value": p,
                       "p_holm": p_holm if analysis == "planned" else np.nan,
                       "rule_out": None, "outcome": None}
                if analysis == "planned" and role == "primary":
                    row["rule_out"] = two_decimals_below(high, gain)
                    row["outcome"] = decision(part, row["diff"], p_holm, high)
                rows.append(row)
    return pd.DataFrame(rows)


def decision(part: str, mean: float, p: float, high: float) -> str:
    """PLAN.md's decision rules, word for word."""
    if part == "paper-width":
        if p <= ALPHA and mean > 0:
            return "reproduced"
        if p <= ALPHA and mean < 0:
            return "contradicted"
        return "inconclusive"
    if p <= ALPHA and mean > 0:
        return "replicated"
    if two_decimals_below(high, 3.0):
        return "not replicated (reversed)" if p <= ALPHA and mean < 0 else "not replicated"
    assert p > ALPHA
    return "inconclusive"


# ---------------------------------------------------------------- fake grids with chosen scores

def chosen_scores(effects: dict[tuple[str, str], np.ndarray], configs: tuple[str, ...],
                  seeds: tuple[int, ...], spread: float = 1.0) -> dict:
    """(config, seed, fold) -> {metric: score}: per fold a base score, plus ``effects[config,
    metric]`` (per fold, default 0), plus a per-seed offset that sums to zero over the seeds
    (and differs between configurations, so each seed's contrast differs from the pooled one).
    Every value is a multiple of 1/4 when the effects are, so fold means are exact."""
    scores = {}
    for c, config in enumerate(configs):
        for k, fold in enumerate(FOLDS):
            for s, offset in zip(seeds, OFFSETS[len(seeds)]):
                scores[config, s, fold] = {
                    metric: 60.0 + 2.5 * k + m + effects.get((config, metric), np.zeros(8))[k]
                    + spread * offset * (1 if c % 2 else -1) * (1 + k % 3)
                    for m, metric in enumerate(METRICS)}
    return scores


def write_scores(grid: Path, scores: dict) -> None:
    """Put ``scores`` into every run's metrics.json (its mean and its one evaluation point)."""
    for (config, seed, fold), values in scores.items():
        path = grid / "runs" / "revised" / "bidirectional" / config / f"seed{seed}" / fold
        data = json.loads((path / "metrics.json").read_text())
        for block in (data["mean"], *data["points"].values()):
            for metric, value in values.items():
                block["gesture"][metric.removeprefix("gesture_")] = value
        (path / "metrics.json").write_text(json.dumps(data))


def project(root: Path, wide: dict | None, narrow: dict | None) -> Path:
    """The repository's layout under ``root``: the committed plan in ``results/confirm`` and the
    grids it names (with ``wide`` and ``narrow`` scores; None: no grid). Returns the plan."""
    (root / "results" / "confirm").mkdir(parents=True)
    plan = root / "results" / "confirm" / "plan.toml"
    shutil.copyfile(PLAN, plan)
    if wide is not None:
        grid = write_fake_grid(root / "results" / "paper" / "grid", seeds=WIDE_SEEDS,
                               hidden=1024, experiments=(*NARROW_EXPERIMENTS,
                                                         Experiment(("APc",))))
        write_scores(grid, wide)
    if narrow is not None:
        grid = write_fake_grid(root / "results" / "confirm" / "h512", seeds=NARROW_SEEDS,
                               hidden=512, experiments=NARROW_EXPERIMENTS)
        write_scores(grid, narrow)
    return plan


def run_confirm(plan: Path, out: Path) -> pd.DataFrame:
    """``multitask-tables confirm`` as a user runs it: its confirm.csv."""
    assert tables_main(["confirm", str(plan), "--out", str(out)]) == 0
    return pd.read_csv(out / "confirm.csv")


def compare(table: pd.DataFrame, expected: pd.DataFrame, tolerance: float) -> None:
    """Every expected row is in ``table`` once, with the same numbers and words."""
    keys = ["part", "family", "analysis", "comparison", "metric"]
    merged = expected.merge(table, on=keys, how="left", suffixes=("", "_code"),
                            validate="one_to_one", indicator=True)
    assert (merged["_merge"] == "both").all(), merged[merged["_merge"] != "both"][keys]
    assert len(table) == len(expected)
    for column in ("diff", "ci_low", "ci_high", "p_value", "p_holm"):
        np.testing.assert_allclose(merged[f"{column}_code"].to_numpy(float),
                                   merged[column].to_numpy(float), rtol=0, atol=tolerance,
                                   err_msg=column)
    for column in ("rule_out", "outcome"):
        code = [None if pd.isna(v) else v for v in merged[f"{column}_code"]]
        ours = [None if v is None or (isinstance(v, float) and np.isnan(v)) else v
                for v in merged[column]]
        if column == "rule_out":        # a CSV reads booleans back as True/False or strings
            code = [None if v is None else str(v) == "True" for v in code]
        assert code == ours, column


def check(tmp_path: Path, wide_effects: dict | None, narrow_effects: dict | None) -> pd.DataFrame:
    """Run the command on grids with these effects and compare every row with the reference,
    from the in-memory table (to 1e-9) and from confirm.csv (to its 4 decimals)."""
    from multitask.evidence.plans.confirm import analyse, read_plan

    wide = (chosen_scores(wide_effects, (A, APOC, APC), WIDE_SEEDS)
            if wide_effects is not None else None)
    narrow = (chosen_scores(narrow_effects, (A, APOC), NARROW_SEEDS)
              if narrow_effects is not None else None)
    plan = project(tmp_path, wide, narrow)
    expected = pd.concat(
        [expected_rows(scores, part, seeds) for scores, part, seeds in
         ((wide, "paper-width", WIDE_SEEDS), (narrow, "replication-512", NARROW_SEEDS))
         if scores is not None], ignore_index=True)
    table, _, _ = analyse(read_plan(plan))
    compare(table, expected, TOLERANCE)
    csv = run_confirm(plan, tmp_path / "results" / "confirm")
    compare(csv, expected, 5e-5 + 1e-12)
    return table.merge(expected[["part", "family", "analysis", "comparison", "metric"]])


def per_fold(values) -> np.ndarray:
    return np.asarray(values, float)


# ---------------------------------------------------------------- the cases

CLEAR = per_fold([4.0, 5.5, 3.25, 6.0, 4.5, 5.0, 3.75, 7.0])
MIXED = per_fold([3.0, -1.5, 2.25, 0.5, -2.0, 4.0, 1.0, -0.75])
SYMMETRIC = per_fold([1.0, -1.0, 2.5, -2.5, 0.75, -0.75, 4.0, -4.0])


@pytest.mark.slow
def test_a_clear_gain_a_null_and_a_clear_loss(tmp_path: Path):
    table = check(tmp_path, {(APOC, "gesture_edit"): CLEAR, (APC, "gesture_edit"): -CLEAR,
                             (APOC, "gesture_f1@10"): MIXED, (APC, "gesture_accuracy"): SYMMETRIC},
                  {(APOC, "gesture_edit"): SYMMETRIC, (APOC, "gesture_accuracy"): CLEAR})
    planned = table[(table.analysis == "planned") & (table.metric == "gesture_edit")]
    assert set(planned.outcome) == {"reproduced", "contradicted", "not replicated"}


@pytest.mark.slow
def test_zeros_and_equal_fold_differences(tmp_path: Path):
    """Zero fold differences still flip (PLAN.md: 2^8 = 256 sign vectors), so 3 zeros and 5
    positive differences are not significant; 8 equal differences are (p = 2/256)."""
    zeros = per_fold([0, 0, 0, 1.5, 2.0, 2.5, 3.0, 3.5])
    table = check(tmp_path, {(APOC, "gesture_edit"): zeros,
                             (APC, "gesture_edit"): np.full(8, 2.25)},
                  {(APOC, "gesture_edit"): np.full(8, 1.0),
                   (APOC, "gesture_f1@10"): np.zeros(8)})
    planned = table[table.analysis == "planned"].set_index(["part", "comparison", "metric"])
    zero_row = planned.loc[("paper-width", f"{APOC} - {A}", "gesture_edit")]
    assert zero_row.p_value == 16 / 256 and zero_row.folds_favouring == "5/8"
    equal = planned.loc[("paper-width", f"{APC} - {A}", "gesture_edit")]
    assert equal.p_value == 2 / 256
    assert equal.ci_low == pytest.approx(2.25, abs=TOLERANCE) == equal.ci_high
    assert planned.loc[("replication-512", f"{APOC} - {A}", "gesture_f1@10"), "p_value"] == 1.0


def scaled(pattern: np.ndarray, high: float) -> np.ndarray:
    """``pattern`` scaled so that its interval's upper end is ``high`` (the test and its
    interval are equivariant)."""
    return pattern * (high / interval_end(pattern, +1))


@pytest.mark.parametrize("high, outcome", [
    (3.0, "inconclusive"),          # exactly 3.0 (MIXED's upper end is 8/3): "reaches +3.0"
    (2.996, "inconclusive"),        # 3.00 with two decimals: not below the paper's 3.0
    (2.994, "not replicated"),      # 2.99
])
def test_the_replication_rule_at_its_boundary(tmp_path: Path, high: float, outcome: str):
    d = MIXED * 9 / 8 if high == 3.0 else scaled(MIXED, high)
    table = check(tmp_path, None, {(APOC, "gesture_edit"): d})
    row = table[(table.analysis == "planned") & (table.metric == "gesture_edit")].iloc[0]
    assert row.p_value > ALPHA and row.outcome == outcome
    assert row.ci_high == pytest.approx(high, abs=TOLERANCE)


@pytest.mark.parametrize("apoc, apc, excluded", [
    (CLEAR / 2, scaled(CLEAR, 2.3), (False, False)),       # CLEAR's upper end is 6.0 exactly
    (scaled(CLEAR, 2.996), scaled(CLEAR, 2.296), (False, False)),
    (scaled(CLEAR, 2.994), scaled(CLEAR, 2.294), (True, True))])
@pytest.mark.slow
def test_the_rule_out_criterion_at_its_boundary(tmp_path: Path, apoc, apc, excluded):
    """The paper's +3.0 and +2.3 against our upper ends with two decimals."""
    table = check(tmp_path, {(APOC, "gesture_edit"): apoc, (APC, "gesture_edit"): apc}, None)
    rows = table[(table.analysis == "planned") & (table.metric == "gesture_edit")]
    rows = rows.set_index("comparison").loc[[f"{APOC} - {A}", f"{APC} - {A}"]]
    assert tuple(rows.rule_out) == excluded and set(rows.outcome) == {"reproduced"}


@pytest.mark.parametrize("spoil", ["unfinished", "unrecorded"])
def test_mixed_seed_counts_are_refused_and_the_other_part_still_analysed(tmp_path: Path, spoil):
    """A fold of part 1 where one configuration has 2 seeds instead of 3 (its third unfinished, or
    never recorded): part 1 gets no row, part 2 its full rows, as the reference computes them."""
    from multitask.evidence.plans.confirm import analyse, read_plan

    narrow = chosen_scores({(APOC, "gesture_edit"): CLEAR}, (A, APOC), NARROW_SEEDS)
    plan = project(tmp_path, chosen_scores({(APOC, "gesture_edit"): CLEAR}, (A, APOC, APC),
                                           WIDE_SEEDS), narrow)
    grid = tmp_path / "results" / "paper" / "grid"
    run = grid / "runs" / "revised" / "bidirectional" / APOC / "seed2" / "F"
    if spoil == "unfinished":
        (run / "finished.json").unlink()
    else:
        shutil.rmtree(run)
        record = json.loads((grid / "grid.json").read_text())
        record["runs"] = [r for r in record["runs"] if not r.endswith(f"{APOC}/seed2/F")]
        (grid / "grid.json").write_text(json.dumps(record))
    table, _, skipped = analyse(read_plan(plan))
    assert set(table.part) == {"replication-512"}
    assert skipped[0].startswith("paper-width: not analysed")
    compare(table, expected_rows(narrow, "replication-512", NARROW_SEEDS), TOLERANCE)


EXPLORATORY = """
[[analyses]]
part = "replication-512"
name = "seed 0 pooled"
borrowed = [{config = "A-fixed", grid = "results/width/h512-a180", seeds = [0]},
            {config = "APoc-gradnorm", grid = "results/width/h512", seeds = [0]}]
"""


def width_grids(root: Path, scores: dict) -> None:
    """PLAN.md's two width grids of seed 0 at 512 units: A's seed 0 taken from ``h512-a180``,
    APoc's from ``h512``; each grid's other configuration scores 0 (it must not be read)."""
    for name, used in (("h512-a180", A), ("h512", APOC)):
        grid = write_fake_grid(root / "results" / "width" / name, seeds=(0,), hidden=512,
                               experiments=NARROW_EXPERIMENTS)
        write_scores(grid, {(config, 0, fold): (scores[used, 0, fold] if config == used
                                                 else dict.fromkeys(METRICS, 0.0))
                            for config in (A, APOC) for fold in FOLDS})


@pytest.mark.slow
def test_the_exploratory_seed_0_analysis_pools_the_width_grids_seed_0(tmp_path: Path):
    """PLAN.md part 2: "labelled exploratory, the same analysis with seed 0 pooled (seeds 0-5;
    A's seed 0 from results/width/h512-a180/, APoc's from results/width/h512/)": in its own
    file, the planned rows as without it."""
    from multitask.evidence.plans.confirm import read_plan
    from multitask.evidence.plans.exploratory import analyse_exploratory, read_exploratory

    narrow = chosen_scores({(APOC, "gesture_edit"): MIXED, (APOC, "gesture_f1@10"): CLEAR},
                           (A, APOC), NARROW_SEEDS)
    seed0 = {(config, 0, fold): {m: 70.0 + 3.0 * k + (5.0 if config == APOC else 0.0)
                                 for m in METRICS}
             for config in (A, APOC) for k, fold in enumerate(FOLDS)}
    plan_path = project(tmp_path, None, narrow)
    out = tmp_path / "results" / "confirm"
    planned_alone = run_confirm(plan_path, out)
    width_grids(tmp_path, seed0)
    (out / "exploratory.toml").write_text(EXPLORATORY)
    assert run_confirm(plan_path, out).equals(planned_alone)
    explored = pd.read_csv(out / "exploratory.csv")
    plan = read_plan(plan_path)
    table, _, notes = analyse_exploratory(plan, read_exploratory(out / "exploratory.toml", plan))
    assert notes == []
    pooled = {**narrow, **seed0}
    all_seeds = (0, *NARROW_SEEDS)
    expected = []
    for family, role, endpoints in [f[1:] for f in FAMILIES if f[0] == "replication-512"]:
        for x, y, metric, gain in endpoints:
            d = np.array([np.mean([pooled[x, s, f][metric] for s in all_seeds])
                          - np.mean([pooled[y, s, f][metric] for s in all_seeds])
                          for f in FOLDS])
            expected.append({"part": "replication-512", "family": family,
                             "analysis": "exploratory: seed 0 pooled",
                             "comparison": f"{x} - {y}", "metric": metric,
                             "diff": float(np.mean(d)), "ci_low": interval_end(d, -1),
                             "ci_high": interval_end(d, +1), "p_value": sign_flip_p(d),
                             "p_holm": np.nan, "rule_out": None, "outcome": None})
    compare(table, pd.DataFrame(expected), TOLERANCE)
    compare(explored, pd.DataFrame(expected), 5e-5 + 1e-12)
    assert set(table.seeds) == {"0 1 2 3 4 5"} and set(explored.role) <= {"primary", "secondary"}


def test_no_exploratory_look_before_the_part_is_complete(tmp_path: Path):
    from multitask.evidence.plans.confirm import read_plan
    from multitask.evidence.plans.exploratory import analyse_exploratory, read_exploratory

    narrow = chosen_scores({}, (A, APOC), NARROW_SEEDS)
    plan_path = project(tmp_path, None, narrow)
    width_grids(tmp_path, chosen_scores({}, (A, APOC), (0, 1, 2)))
    (tmp_path / "results/confirm/h512/runs/revised/bidirectional/A-fixed/seed5/I"
     / "finished.json").unlink()
    path = tmp_path / "results" / "confirm" / "exploratory.toml"
    path.write_text(EXPLORATORY)
    plan = read_plan(plan_path)
    table, _, notes = analyse_exploratory(plan, read_exploratory(path, plan))
    assert table.empty and notes == [
        "replication-512, exploratory: seed 0 pooled: not computed, the part is not analysed"]


def test_borrowed_runs_of_other_settings_are_not_pooled(tmp_path: Path):
    from multitask.evidence.plans.confirm import read_plan
    from multitask.evidence.plans.exploratory import analyse_exploratory, read_exploratory

    plan_path = project(tmp_path, None, chosen_scores({}, (A, APOC), NARROW_SEEDS))
    width_grids(tmp_path, chosen_scores({}, (A, APOC), (0, 1, 2)))
    config = tmp_path / "results/width/h512/runs/revised/bidirectional/APoc-gradnorm/seed0/B"
    data = json.loads((config / "config.json").read_text())
    data["run"]["encoder"]["hidden"] = 1024
    (config / "config.json").write_text(json.dumps(data))
    path = tmp_path / "results" / "confirm" / "exploratory.toml"
    path.write_text(EXPLORATORY)
    plan = read_plan(plan_path)
    table, _, notes = analyse_exploratory(plan, read_exploratory(path, plan))
    assert table.empty and "not computed" in notes[0] and "run.encoder.hidden" in notes[0]
