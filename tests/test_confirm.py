"""The pre-registered confirmatory analysis (``multitask.evidence.plans.confirm``,
``multitask-tables confirm``)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.plans.confirm import Part, PlanError, analyse, outcome, read_plan
from multitask.evidence.runs.collect import run_rows
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
    table, per_fold, skipped = analyse(read_plan(project / "confirm" / "plan.toml"))
    assert table.empty and per_fold.empty and list(per_fold.columns) == [
        "part", "analysis", "comparison", "metric", "fold", "difference"]
    assert skipped[0] == ("wide: not analysed, 71 of 72 runs of seeds 0 1 2 in grids/wide "
                          "finished (the plan analyses complete grids only): not finished: "
                          "grids/wide/runs/revised/bidirectional/APc-fixed/seed2/D")


def _unrecord(grid: Path, *runs: str) -> None:
    """Delete ``runs`` (folders under ``runs/revised/bidirectional``) and their lines in
    grid.json, as if the grid had never planned them."""
    record = json.loads((grid / "grid.json").read_text())
    for run in runs:
        shutil.rmtree(grid / "runs/revised/bidirectional" / run)
        record["runs"] = [r for r in record["runs"] if f"revised/bidirectional/{run}" not in r]
    (grid / "grid.json").write_text(json.dumps(record))


def _edit_json(path: Path, change) -> None:
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


def _no_edit(data: dict) -> None:
    for block in (data["mean"], *data["points"].values()):
        block["gesture"]["edit"] = None


INCOMPLETE = {
    # a fold no run of one configuration has, and that grid.json does not record either
    "a fold missing": (lambda grid: _unrecord(grid, *(f"APc-fixed/seed{s}/D" for s in (0, 1, 2))),
                       "APc-fixed does not have seeds 0 1 2 on every fold"),
    # a seed missing for one configuration, not recorded either
    "a seed missing": (lambda grid: _unrecord(grid, "APoc-gradnorm/seed1"),
                       "APoc-gradnorm does not have seeds 0 1 2 on every fold"),
    "a NaN score": (lambda grid: _edit_json(
        grid / "runs/revised/bidirectional/A-fixed/seed0/C/metrics.json", _no_edit),
        "metric"),
    "a run of another width": (lambda grid: _edit_json(
        grid / "runs/revised/bidirectional/A-fixed/seed1/E/config.json",
        lambda data: data["run"]["encoder"].update(hidden=32)), "run.encoder.hidden"),
    "a stray seed": (lambda grid: shutil.copytree(
        grid / "runs/revised/bidirectional/A-fixed/seed2",
        grid / "runs/revised/bidirectional/A-fixed/seed3"), "stray folder"),
}


@pytest.mark.parametrize("case", INCOMPLETE)
def test_a_grid_that_is_not_the_plans_design_is_not_analysed(project: Path, case: str):
    """Every way a grid can fall short of the plan's design leaves its part without rows and
    says why, and never stops another part from being analysed."""
    spoil, reason = INCOMPLETE[case]
    spoil(project / "grids" / "wide")
    table, _, skipped = analyse(read_plan(project / "confirm" / "plan.toml"))
    assert table.empty
    assert skipped[0].startswith("wide: not analysed") and reason in skipped[0]


def test_a_part_at_another_width_than_the_plans_is_not_analysed(project: Path):
    plan = project / "confirm" / "plan.toml"
    plan.write_text(PLAN.replace('grid = "grids/wide"', 'grid = "grids/wide"\nhidden = 1024'))
    table, _, skipped = analyse(read_plan(plan))
    assert table.empty and "lstm-16, but the plan's part is at 1024 units" in skipped[0]
    plan.write_text(PLAN.replace('grid = "grids/wide"', 'grid = "grids/wide"\nhidden = 16'))
    assert not analyse(read_plan(plan))[0].empty


def test_a_recorded_seed_outside_the_plan_is_left_out(project: Path):
    """A seed the grid records but the plan does not name (seed 3) is not pooled."""
    grid = project / "grids" / "wide"
    before = analyse(read_plan(project / "confirm" / "plan.toml"))[0]
    runs = grid / "runs/revised/bidirectional/APc-fixed"
    shutil.copytree(runs / "seed2", runs / "seed3")
    for config in (runs / "seed3").glob("*/config.json"):
        _edit_json(config, lambda data: data["run"]["train"].update(seed=3))
    _edit_json(grid / "grid.json", lambda data: data["runs"].extend(
        run.replace("seed2", "seed3") for run in list(data["runs"]) if "APc-fixed/seed2" in run))
    after = analyse(read_plan(project / "confirm" / "plan.toml"))[0]
    pd.testing.assert_frame_equal(before, after)


@pytest.mark.parametrize("mean, p, high, expected", [
    (2.0, 0.01, 4.0, "replicated"), (0.5, 0.2, 2.0, "not replicated"),
    (-2.0, 0.01, -0.5, "not replicated (reversed)"), (1.0, 0.2, 3.5, "inconclusive"),
    # the boundaries: p exactly 0.05; an upper end of 3.0, or of 3.00 at two decimals (PLAN.md:
    # "ours with two decimals"), reaches +3.0; 2.99 lies below it
    (0.5, 0.05, 3.5, "replicated"), (0.5, 0.2, 3.0, "inconclusive"),
    (0.5, 0.2, 2.996, "inconclusive"), (0.5, 0.2, 2.994, "not replicated"),
    (0.0, 1.0, 2.0, "not replicated"),
    # "reversed" needs a mean below 0, "replicated" one above (PLAN.md), whatever p says
    (0.0, 0.01, 1.0, "not replicated")])
def test_the_replication_rule(mean, p, high, expected):
    part = Part("r", "r", Path("."), (1,), (), ("replicated", "not replicated", "inconclusive"),
                rule_out_below=3.0)
    assert outcome(part, mean, p, high, 0.05) == expected


def test_the_claim_rule():
    part = Part("c", "c", Path("."), (1,), (), ("reproduced", "contradicted", "inconclusive"))
    assert outcome(part, 1.0, 0.04, 2.0, 0.05) == "reproduced"
    assert outcome(part, -1.0, 0.04, -0.1, 0.05) == "contradicted"
    assert outcome(part, 1.0, 0.06, 2.0, 0.05) == "inconclusive"
    assert outcome(part, 1.0, 0.05, 2.0, 0.05) == "reproduced"
    assert outcome(part, -1.0, 0.05, -0.1, 0.05) == "contradicted"
    # PLAN.md: contradicted needs "the mean fold difference < 0"; a mean of 0 is "otherwise"
    assert outcome(part, 0.0, 0.04, 1.0, 0.05) == "inconclusive"


@pytest.mark.parametrize("apoc_high, excluded", [(3.0, False), (2.996, False), (2.994, True)])
def test_the_rule_out_criterion_reads_our_upper_end_with_two_decimals(project: Path, monkeypatch,
                                                                     apoc_high, excluded):
    """PLAN.md: "The paper's gains are compared to the interval with their published digit and
    ours with two decimals": an upper end of 2.996 is 3.00, not below the paper's +3.0."""
    from multitask.evidence.plans import confirm

    real = confirm.paired

    def with_upper_end(runs, contrast, metric, config):
        result = real(runs, contrast, metric, config)
        if contrast.label == "APoc-gradnorm - A-fixed" and metric == "gesture_edit":
            monkeypatch.setattr(type(result), "ci", property(lambda r: (
                (1.0, apoc_high) if r.contrast == "APoc-gradnorm - A-fixed"
                and r.metric == "gesture_edit" else r.test.interval())))
        return result

    monkeypatch.setattr(confirm, "paired", with_upper_end)
    table, _, _ = analyse(read_plan(project / "confirm" / "plan.toml"))
    row = table[(table.analysis == "planned") & (table.metric == "gesture_edit")
                & (table.comparison == "APoc-gradnorm - A-fixed")].iloc[0]
    assert row.ci_high == apoc_high and row.rule_out == excluded
    assert row.paper_in_ci == (not excluded)


@pytest.mark.parametrize("old, new, message", [
    ('role = "secondary"', 'role = "tertiary"',
     r"plan.toml: parts\[0\].families\[1\].role must be one"),
    ("paper_gain = 2.3", 'paper_gain = "2.3"', r"endpoints\[1\].paper_gain must be a float"),
    ("sensitivity_seeds", "sensitivty_seeds",
     r"parts\[0\].sensitivty_seeds: not a key of a plan's part"),
    ("seeds = [1, 2]\noutcomes", 'seeds = [1, "2"]\noutcomes',
     r"parts\[0\].sensitivity_seeds must be a list of distinct"),
    ("sensitivity_seeds = [1, 2]", "sensitivity_seeds = [1, 3]",
     r"sensitivity_seeds must be some of the part's seeds"),
    # a family that tests nothing, and two parts of one name (their rows and lines would mix)
    ('endpoints = [{x = "APoc-gradnorm", y = "A-fixed", metric = "gesture_accuracy", '
     'paper_gain = 0.7}]', "endpoints = []", r"parts\[0\].families\[1\].endpoints must not be"),
    ('name = "replication"\ntitle', 'name = "wide"\ntitle', r"parts: two parts of one name"),
])
def test_a_plan_with_a_mistyped_key_is_one_named_error(tmp_path: Path, old: str, new: str,
                                                       message: str):
    assert old in PLAN
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.replace(old, new))
    with pytest.raises(PlanError, match=message):
        read_plan(plan)


def test_the_committed_plan_reads():
    plan = read_plan(Path(__file__).resolve().parents[1] / "results/confirm/plan.toml")
    assert [(p.name, p.hidden, p.seeds) for p in plan.parts] == [
        ("paper-width", 1024, (0, 1, 2)), ("replication-512", 512, (1, 2, 3, 4, 5))]
    assert [[len(f.endpoints) for f in p.families] for p in plan.parts] == [[2, 4], [1, 2]]


def test_the_command_writes_the_analysis_from_any_folder(project: Path, tmp_path: Path,
                                                         monkeypatch, capsys):
    monkeypatch.chdir(tmp_path.parent)
    out = project / "confirm"
    assert tables_main(["confirm", str(out / "plan.toml"), "--out", str(out)]) == 0
    table = pd.read_csv(out / "confirm.csv")
    assert set(table.part) == {"wide"} and "replication: not analysed" in capsys.readouterr().err
    assert (out / "plan.toml").read_text() == PLAN              # the plan is never written
    first = (out / "confirm.csv").read_bytes()
    assert tables_main(["confirm", str(out / "plan.toml"), "--out", str(out)]) == 0
    assert (out / "confirm.csv").read_bytes() == first
    with pytest.raises(SystemExit):
        tables_main(["confirm", str(out / "plan.toml"), "--out", str(out), "--seeds", "0"])
    assert np.isfinite(table["diff"]).all()


def test_a_tie_lost_to_float_rounding_still_counts():
    """A fold difference that is 0 but computed as 5.6e-17 (0.1 + 0.2 - 0.3), or folds whose
    differences sum to 0 up to rounding, count as the exact ties they are: the p-value and the
    interval do not depend on how the seed means were rounded."""
    from multitask.evidence.statistics.paired import SignFlip

    exact = np.array([0.0, 1.0, 2.0, 1.5, 0.5, 3.0, 1.0, 2.5])
    rounded = exact.copy()
    rounded[0] = 0.1 + 0.2 - 0.3
    assert SignFlip(rounded).p_value() == SignFlip(exact).p_value() == 4 / 256
    pattern = np.array([3.0, -1.5, 2.25, 0.5, -2.0, 4.0, 1.0, -0.75])   # -1.5 + 0.5 + 1.0 = 0
    scaled = pattern * (2.994 / 2.6666666666666665)
    assert SignFlip(scaled).p_value() == SignFlip(pattern).p_value() == 43 / 128
    assert SignFlip(scaled).interval() == pytest.approx(
        tuple(2.994 / 2.6666666666666665 * e for e in SignFlip(pattern).interval()), abs=1e-9)


#: The provenance of the commit that trained seed 0 at 1024 units.
SEED_0_COMMIT = {"git_commit": "9a820fde116d82e4e16f3c0edbc8f2077d4a4068", "git_dirty": False}


def _stamp(paths, provenance: dict) -> None:
    """Record ``provenance`` in each of the JSON files ``paths``."""
    for path in paths:
        _edit_json(path, lambda data: data.update(provenance=provenance))


def _commits(project: Path) -> pd.Series:
    """The ``commits`` column of the planned analysis, by analysis, comparison and metric."""
    table, _, _ = analyse(read_plan(project / "confirm" / "plan.toml"))
    return table.set_index(["analysis", "comparison", "metric"]).commits


def test_each_row_names_the_commits_that_trained_its_runs(project: Path):
    """PLAN.md names the commit whose code trains each part; the pooling rule compares settings,
    not code, so every row says which commits trained the runs behind it."""
    grid = project / "grids" / "wide"
    _stamp(grid.glob("runs/*/*/*/*/*/config.json"), SEED_0_COMMIT)
    _stamp([grid / "runs/revised/bidirectional/APc-fixed/seed1/C/config.json"],
           {"git_commit": "0123456789", "git_dirty": True})
    commits = _commits(project)
    assert commits["planned", "APc-fixed - A-fixed", "gesture_edit"] == "0123456-dirty 9a820fd"
    assert commits["seed 0", "APc-fixed - A-fixed", "gesture_edit"] == "9a820fd"
    assert commits["planned", "APoc-gradnorm - A-fixed", "gesture_edit"] == "9a820fd"


def test_a_run_finished_by_another_checkout_names_both_commits(project: Path):
    """A run resumed from its checkpoint by a session of another checkout: config.json records
    the session that started it, finished.json the one that finished it; both trained it."""
    grid = project / "grids" / "wide"
    _stamp([*grid.glob("runs/*/*/*/*/*/config.json"), *grid.glob("runs/*/*/*/*/*/finished.json")],
           SEED_0_COMMIT)
    _stamp([grid / "runs/revised/bidirectional/APoc-gradnorm/seed2/E/finished.json"],
           {"git_commit": "fedcba9876", "git_dirty": True})
    commits = _commits(project)
    assert commits["planned", "APoc-gradnorm - A-fixed", "gesture_edit"] == "9a820fd fedcba9-dirty"
    assert commits["seed 2", "APoc-gradnorm - A-fixed", "gesture_edit"] == "9a820fd fedcba9-dirty"
    assert commits["seed 1", "APoc-gradnorm - A-fixed", "gesture_edit"] == "9a820fd"
    assert commits["planned", "APc-fixed - A-fixed", "gesture_edit"] == "9a820fd"


# --- The report (confirm.md) ----------------------------------------------------------------

def _report(project: Path, plan_text: str = PLAN) -> tuple[str, pd.DataFrame]:
    """confirm.md and confirm.csv as the command writes them for ``plan_text``."""
    out = project / "confirm"
    (out / "plan.toml").write_text(plan_text)
    assert tables_main(["confirm", str(out / "plan.toml"), "--out", str(out)]) == 0
    return (out / "confirm.md").read_text(), pd.read_csv(out / "confirm.csv")


def test_the_report_gives_each_primary_outcome_in_the_plans_words_first(project: Path):
    text, table = _report(project, PLAN.replace("paper_gain = 2.3", "paper_gain = 9.0"))
    planned = table[(table.analysis == "planned") & (table.role == "primary")]
    for row in planned.itertuples(index=False):
        line = f"- {row.comparison}, gesture edit: **{row.outcome}**"
        assert line in text
        excluded = f"the paper's gain of {row.paper_gain:+.1f} is excluded"
        assert (f"{line}; {excluded}" in text) == bool(row.rule_out)
    assert planned.rule_out.any() and not planned.rule_out.all()      # both cases met
    claim = text.index("## a claim")
    order = [text.index(marker, claim) for marker in (
        "**", "Per seed and sensitivity", "### Family secondary", "## a replication")]
    assert order == sorted(order)                   # outcome, descriptive, secondary, next part
    assert "## a replication\n\nreplication: not analysed" in text
    assert text.count("**") == 2 * len(planned)     # only the planned outcomes are bold


def test_the_reports_numbers_are_the_analysis_rounded_as_the_plan_says(project: Path):
    text, _ = _report(project)
    table, _, _ = analyse(read_plan(project / "confirm" / "plan.toml"))
    for row in table.itertuples(index=False):
        assert f"{row.diff:+.2f}" in text
        if row.analysis != "planned" and len(row.seeds.split()) == 1:
            continue
        assert f"{row.ci_low:.2f} to {row.ci_high:.2f}" in text and f"{row.p_value:.4f}" in text
    assert "| +3.0 |" in text and "| +2.3 |" in text             # the paper's published digit
    header = next(line for line in text.splitlines() if line.startswith("| endpoint | planned"))
    assert header.split(" | ")[2:] == ["seed 0", "seed 1", "seed 2",
                                       "sensitivity (seeds 1 2) |"]


def test_the_report_labels_exploratory_rows_and_keeps_them_out_of_the_outcomes(project: Path):
    from multitask.evidence.plans.confirm_report import confirm_markdown

    plan = read_plan(project / "confirm" / "plan.toml")
    table, _, skipped = analyse(plan)
    explored = table[table.analysis == "planned"].assign(analysis="exploratory: seed 9 pooled",
                                                         outcome=None, p_holm=np.nan)
    text = confirm_markdown(plan, table, skipped, explored, [])
    section = text.index("### Exploratory (not part of the plan's test")
    assert text.index("exploratory: seed 9 pooled") > section
    assert text.count("**") == confirm_markdown(plan, table, skipped, explored.iloc[:0],
                                                []).count("**")


def test_the_report_names_the_plans_confidence(project: Path):
    """The interval's level in the report is the plan's, never a fixed 95 %."""
    text, table = _report(project, PLAN.replace("confidence = 0.95", "confidence = 0.9"))
    assert "90 % interval" in text and "95 %" not in text
    row = table[(table.analysis == "planned")].iloc[0]
    assert f"{row.ci_low:.2f} to {row.ci_high:.2f}" in text


def test_a_part_without_sensitivity_seeds_reports_no_sensitivity_analysis(project: Path):
    """Part 2 of PLAN.md names no sensitivity analysis: its report must not mention one."""
    text, table = _report(project, PLAN.replace("sensitivity_seeds = [1, 2]\n", ""))
    assert "sensitivity" not in set(table.analysis) and "sensitivity" not in text.lower()
    assert "Per seed (descriptive: no correction, no outcome)" in text
    header = next(line for line in text.splitlines() if line.startswith("| endpoint | planned"))
    assert header.split(" | ")[2:] == ["seed 0", "seed 1", "seed 2 |"]


def test_a_file_of_the_reports_name_is_replaced_only_with_overwrite(project: Path, capsys):
    """A confirm.md the command did not write is refused, and the refusal's advice (--overwrite)
    is an option multitask-tables confirm takes."""
    out = project / "elsewhere"
    out.mkdir()
    (out / "confirm.md").write_text("mine\n")
    command = ["confirm", str(project / "confirm" / "plan.toml"), "--out", str(out)]
    assert tables_main(command) == 2
    assert "(--overwrite)" in capsys.readouterr().err
    assert (out / "confirm.md").read_text() == "mine\n" and not (out / "confirm.csv").exists()
    assert tables_main(command + ["--overwrite"]) == 0
    assert (out / "confirm.md").read_text().startswith("# Confirmatory analysis")


def test_what_the_command_writes_does_not_depend_on_where_the_checkout_or_the_user_is(
        project: Path, tmp_path_factory, monkeypatch):
    """Paths in confirm.md are the plan's (``results/...``), not this machine's; a grid is
    looked for beside the plan, never in the current folder."""
    (project / "grids/wide/runs/revised/bidirectional/APc-fixed/seed1/C/finished.json").unlink()
    elsewhere = tmp_path_factory.mktemp("elsewhere")
    shutil.copytree(project, elsewhere / "project")
    user = tmp_path_factory.mktemp("user")
    (user / "grids" / "not-yet").mkdir(parents=True)            # a decoy where the user stands
    monkeypatch.chdir(user)
    reports = []
    for root in (project, elsewhere / "project"):
        out = root / "confirm"
        assert tables_main(["confirm", str(out / "plan.toml"), "--out", str(out)]) == 0
        reports.append((out / "confirm.md").read_text())
    assert reports[0] == reports[1]
    assert str(project) not in reports[0] and str(elsewhere) not in reports[0]
    assert "wide: not analysed, 71 of 72 runs of seeds 0 1 2 in grids/wide finished" in reports[0]
    assert "replication: not analysed, its grid grids/not-yet does not exist (yet)" in reports[0]
