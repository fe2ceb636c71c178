"""The pre-registered confirmatory analysis (``multitask.evidence.confirm``, ``--confirm``)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.collect import run_rows
from multitask.evidence.confirm import Part, PlanError, analyse, outcome, read_plan
from multitask.grid.spec import Experiment
from tests.fake_grid import FOLDS, write_fake_grid

EXPERIMENTS = (Experiment(("A",)), Experiment(("APoc",), ("gradnorm",)), Experiment(("APc",)))
PLAN = """
confidence = 0.95

[[parts]]
name = "wide"
title = "a claim"
grid = "grids/wide"
seeds = [0, 1, 2]
sensitivity_seeds = [1, 2]
outcomes = ["reproduced", "contradicted", "inconclusive"]

[[parts.families]]
name = "primary"
role = "primary"
endpoints = [
    {x = "APoc-gradnorm", y = "A-fixed", metric = "gesture_edit", paper_gain = 3.0},
    {x = "APc-fixed", y = "A-fixed", metric = "gesture_edit", paper_gain = 2.3},
]

[[parts.families]]
name = "secondary"
role = "secondary"
endpoints = [{x = "APoc-gradnorm", y = "A-fixed", metric = "gesture_accuracy", paper_gain = 0.7}]

[[parts]]
name = "replication"
title = "a replication"
grid = "grids/not-yet"
seeds = [1, 2]
outcomes = ["replicated", "not replicated", "inconclusive"]
rule_out_below = 3.0

[[parts.families]]
name = "replication"
role = "primary"
endpoints = [{x = "APoc-gradnorm", y = "A-fixed", metric = "gesture_edit", paper_gain = 3.0}]
"""


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """A project folder: the plan in ``confirm/``, its first part's grid (complete, 3 seeds) in
    ``grids/wide`` with APoc's edit raised by 25 points on every run; the second part's grid
    not there."""
    grid = write_fake_grid(tmp_path / "grids" / "wide", seeds=(0, 1, 2),
                           experiments=EXPERIMENTS)
    for metrics in (grid / "runs").glob("*/*/APoc-gradnorm/*/*/metrics.json"):
        data = json.loads(metrics.read_text())
        for scores in (data["mean"]["gesture"], *(p["gesture"] for p in data["points"].values())):
            scores["edit"] += 25.0
        metrics.write_text(json.dumps(data))
    (tmp_path / "confirm").mkdir()
    (tmp_path / "confirm" / "plan.toml").write_text(PLAN)
    return tmp_path


def test_the_planned_analysis_pools_the_seeds_within_each_fold(project: Path):
    table, per_fold, skipped = analyse(read_plan(project / "confirm" / "plan.toml"))
    planned = table[table.analysis == "planned"].set_index("comparison")
    runs, _ = run_rows(project / "grids" / "wide")
    means = runs.groupby(["variant", "fold"]).gesture_edit.mean()
    expected = (means["APoc"] - means["A"]).reindex(list(FOLDS))
    row = planned[planned.metric == "gesture_edit"].loc["APoc-gradnorm - A-fixed"]
    assert row["diff"] == pytest.approx(expected.mean())
    assert row.folds == 8 and row.seeds == "0 1 2" and row.folds_favouring == "8/8"
    # every fold favours APoc: the smallest exact p, Holm over the family's 2 primaries
    assert row.p_value == pytest.approx(2 / 2 ** 8)
    assert row.p_holm == pytest.approx(2 * 2 / 2 ** 8)
    assert row.outcome == "reproduced" and row.ci_low > 0
    assert row.rule_out == (row.ci_high < 3.0)
    folds = per_fold[(per_fold.analysis == "planned") & (per_fold.metric == "gesture_edit")
                     & (per_fold.comparison == "APoc-gradnorm - A-fixed")]
    assert folds.set_index("fold").difference.to_numpy() == pytest.approx(expected.to_numpy())
    # descriptive rows: the sensitivity seeds and each seed alone, without outcome or Holm
    assert set(table.analysis) == {"planned", "sensitivity", "seed 0", "seed 1", "seed 2"}
    described = table[table.analysis != "planned"]
    assert described.outcome.isna().all() and described.p_holm.isna().all()
    seed_means = table[(table.analysis.str.startswith("seed ")) & (table.metric == "gesture_edit")
                       & (table.comparison == "APoc-gradnorm - A-fixed")]["diff"]
    assert seed_means.mean() == pytest.approx(row["diff"])     # balanced: the mean of the seeds'
    secondary = planned[planned.metric == "gesture_accuracy"]
    assert secondary.outcome.isna().all() and secondary.p_holm.notna().all()
    assert skipped == ["replication: not analysed, its grid grids/not-yet does not exist (yet)"]


def test_an_unfinished_grid_is_not_analysed(project: Path):
    grid = project / "grids" / "wide"
    (grid / "runs/revised/bidirectional/APc-fixed/seed2/D/finished.json").unlink()
    table, _, skipped = analyse(read_plan(project / "confirm" / "plan.toml"))
    assert table.empty
    assert skipped[0] == (f"wide: not analysed, 71 of 72 runs of seeds 0 1 2 in {grid} finished "
                          "(the plan analyses complete grids only)")


@pytest.mark.parametrize("mean, p, high, expected", [
    (2.0, 0.01, 4.0, "replicated"), (0.5, 0.2, 2.0, "not replicated"),
    (-2.0, 0.01, -0.5, "not replicated (reversed)"), (1.0, 0.2, 3.5, "inconclusive")])
def test_the_replication_rule(mean, p, high, expected):
    part = Part("r", "r", Path("."), (1,), (), ("replicated", "not replicated", "inconclusive"),
                rule_out_below=3.0)
    assert outcome(part, mean, p, high, 0.05) == expected


def test_the_claim_rule():
    part = Part("c", "c", Path("."), (1,), (), ("reproduced", "contradicted", "inconclusive"))
    assert outcome(part, 1.0, 0.04, 2.0, 0.05) == "reproduced"
    assert outcome(part, -1.0, 0.04, -0.1, 0.05) == "contradicted"
    assert outcome(part, 1.0, 0.06, 2.0, 0.05) == "inconclusive"


def test_a_plan_with_a_mistyped_key_is_one_named_error(tmp_path: Path):
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.replace('role = "secondary"', 'role = "tertiary"'))
    with pytest.raises(PlanError, match=r"plan.toml: parts\[0\].families\[1\].role must be one"):
        read_plan(plan)
    plan.write_text(PLAN.replace("paper_gain = 2.3", 'paper_gain = "2.3"'))
    with pytest.raises(PlanError, match=r"endpoints\[1\].paper_gain must be a float"):
        read_plan(plan)


def test_the_command_writes_the_analysis_from_any_folder(project: Path, tmp_path: Path,
                                                         monkeypatch, capsys):
    monkeypatch.chdir(tmp_path.parent)
    out = project / "confirm"
    assert tables_main(["--confirm", str(out / "plan.toml"), "--out", str(out)]) == 0
    table = pd.read_csv(out / "confirm.csv")
    assert set(table.part) == {"wide"} and "replication: not analysed" in capsys.readouterr().err
    assert (out / "plan.toml").read_text() == PLAN              # the plan is never written
    first = (out / "confirm.csv").read_bytes()
    assert tables_main(["--confirm", str(out / "plan.toml"), "--out", str(out)]) == 0
    assert (out / "confirm.csv").read_bytes() == first
    with pytest.raises(SystemExit):
        tables_main(["--confirm", str(out / "plan.toml"), "--out", str(out), "--seeds", "0"])
    assert np.isfinite(table["diff"]).all()
