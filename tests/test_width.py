"""The width study (``multitask-tables width GRID GRID ...``) on fake grids of several widths."""
from __future__ import annotations

import json
import shutil

import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.render.paper_results import TABLE_1
from multitask.evidence.runs.collect import run_rows
from multitask.grid.spec import Experiment
from tests.fake_grid import FOLDS, write_fake_grid

MODELS = (Experiment(variants=("A",)), Experiment(variants=("APoc",), weightings=("gradnorm",)))


def _grid(root, hidden, seeds=(0,), epochs=12):
    return write_fake_grid(root / f"h{hidden}", seeds=seeds, hidden=hidden, epochs=epochs,
                           experiments=MODELS, schedule_factors={"APoc": 1.5})


def _fold_means(grid, variant, metric):
    runs, _ = run_rows(grid)
    return runs[runs.variant == variant].groupby("fold")[metric].mean()


@pytest.mark.slow
def test_one_row_per_width_and_metric_from_each_grids_runs(tmp_path, capsys):
    small, paper = _grid(tmp_path, 32), _grid(tmp_path, 1024, seeds=(0, 1))
    assert tables_main(["width", str(paper), str(small), "--out", str(tmp_path / "w")]) == 0
    table = pd.read_csv(tmp_path / "w" / "width.csv")
    assert list(table.hidden) == [32] * 3 + [1024] * 3
    assert (tmp_path / "w" / "width.png").is_file() and (tmp_path / "w" / "width.pdf").is_file()
    row = table[(table.hidden == 1024) & (table.metric == "gesture_edit")].iloc[0]
    a, apoc = (_fold_means(paper, v, "gesture_edit") for v in ("A", "APoc"))
    assert row.A_mean == pytest.approx(a.mean(), abs=1e-4)
    assert row.A_std == pytest.approx(a.std(ddof=1), abs=1e-4)
    assert row["diff"] == pytest.approx((apoc - a).mean(), abs=1e-4)
    assert row.ci_low <= row["diff"] <= row.ci_high
    assert (row.folds, row.seeds) == (len(FOLDS), "0 1")
    assert (row.A_epochs, row.APoc_epochs) == (12, 18)
    assert (row.A_runs, row.APoc_runs) == (2 * len(FOLDS), 2 * len(FOLDS))
    assert 0 <= row.A_converged + row.A_undecided + row.A_still_falling <= row.A_runs
    paper_edit = TABLE_1["A-fixed"]["gesture_edit"][0], TABLE_1["APoc-gradnorm"]["gesture_edit"][0]
    assert (row.paper_A, row.paper_APoc) == pytest.approx(paper_edit)
    assert table[table.hidden == 32].paper_A.isna().all()


def test_holm_corrects_each_metric_over_the_widths(tmp_path):
    grids = [_grid(tmp_path, hidden) for hidden in (32, 64, 128)]
    assert tables_main(["width", str(grids[0]), *map(str, grids[1:]),
                        "--out", str(tmp_path / "w")]) == 0
    table = pd.read_csv(tmp_path / "w" / "width.csv")
    for _, family in table.groupby("metric"):
        assert (family.p_holm >= family.p_value - 1e-4).all()
        assert (family.p_holm <= 1).all()
        smallest = family.p_value.idxmin()          # Holm's first step: m times the smallest p
        assert family.p_holm[smallest] == pytest.approx(min(1, 3 * family.p_value[smallest]),
                                                        abs=1e-3)


def test_a_seed_still_training_is_left_out(tmp_path):
    grid = _grid(tmp_path, 64, seeds=(0, 1))
    (grid / "runs/revised/bidirectional/APoc-gradnorm/seed1/C/finished.json").unlink()
    assert tables_main(["width", str(grid), str(_grid(tmp_path, 16)),
                        "--out", str(tmp_path / "w")]) == 0
    table = pd.read_csv(tmp_path / "w" / "width.csv", dtype={"seeds": str})
    assert set(table[table.hidden == 64].seeds) == {"0"}


def test_two_grids_of_one_width_are_a_one_line_error(tmp_path, capsys):
    grid = _grid(tmp_path, 32)
    assert tables_main(["width", str(grid), str(grid), "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "one entry per width, got widths [32, 32]" in err and "Traceback" not in err
    assert not (tmp_path / "w").exists()


def test_seeds_restrict_every_grid(tmp_path):
    small, paper = _grid(tmp_path, 32, seeds=(0, 1)), _grid(tmp_path, 1024, seeds=(0, 1))
    assert tables_main(["width", str(small), str(paper), "--seeds", "1",
                        "--out", str(tmp_path / "w")]) == 0
    table = pd.read_csv(tmp_path / "w" / "width.csv", dtype={"seeds": str})
    assert set(table.seeds) == {"1"} and set(table.A_runs) == {len(FOLDS)}


def test_a_grid_without_a_finished_seed_names_what_it_lacks(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    for fold in FOLDS[3:]:
        (grid / f"runs/revised/bidirectional/APoc-gradnorm/seed0/{fold}/finished.json").unlink()
    assert tables_main(["width", str(_grid(tmp_path, 16)), str(grid),
                        "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "seed 0: APoc-gradnorm 3 of 8 runs finished" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "w").exists()


def test_a_run_without_usable_metrics_is_one_line_naming_it(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    metrics = grid / "runs/revised/bidirectional/A-fixed/seed0/D/metrics.json"
    metrics.write_text("{")
    assert tables_main(["width", str(_grid(tmp_path, 16)), str(grid),
                        "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert str(metrics) in err and len(err.strip().splitlines()) == 1


def test_grids_on_other_folds_are_refused(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    record = grid / "grid.json"
    runs = json.loads(record.read_text())["runs"]
    record.write_text(json.dumps({"runs": [run for run in runs if not run.endswith("/I")]}))
    for config in ("A-fixed", "APoc-gradnorm"):
        (grid / f"runs/revised/bidirectional/{config}/seed0/I").rename(tmp_path / config)
    assert tables_main(["width", str(_grid(tmp_path, 16)), str(grid),
                        "--out", str(tmp_path / "w")]) == 2
    assert "the grids differ in their folds" in capsys.readouterr().err


def test_grids_on_other_data_settings_are_refused(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    for path in grid.glob("runs/**/config.json"):
        config = json.loads(path.read_text())
        config["run"]["data"]["preprocessing"]["cutoff_hz"] = 2.0
        path.write_text(json.dumps(config))
    assert tables_main(["width", str(_grid(tmp_path, 16)), str(grid),
                        "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "the grids differ in their data settings (preprocessing)" in err


def test_seeds_no_grid_has_are_named(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    assert tables_main(["width", str(_grid(tmp_path, 16)), str(grid), "--seeds", "5",
                        "--out", str(tmp_path / "w")]) == 2
    assert "no run of A-fixed or APoc-gradnorm of seed(s) 5" in capsys.readouterr().err


@pytest.mark.parametrize("options,message", [
    ([], "the following arguments are required: --out"),
    (["--out", "W", "--allow-incomplete"], "width takes no --allow-incomplete option"),
    (["--out", "W", "--no-figures"], "width takes no --no-figures option")])
def test_width_takes_out_seeds_and_overwrite_alone(tmp_path, capsys, options, message):
    grid = _grid(tmp_path, 32)
    options = [str(tmp_path / "w") if word == "W" else word for word in options]
    with pytest.raises(SystemExit) as exit_:
        tables_main(["width", str(grid), str(grid), *options])
    assert exit_.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.parametrize("options", [[], ["--allow-incomplete"], ["--no-figures"]])
def test_the_flag_form_still_takes_out_alone(tmp_path, capsys, options):
    grid = _grid(tmp_path, 32)
    out = ["--out", str(tmp_path / "w")] if options else []
    with pytest.raises(SystemExit) as exit_:
        tables_main([str(grid), "--widths", str(grid), *out, *options])
    assert exit_.value.code == 2
    assert "--widths needs --out and takes no other option" in capsys.readouterr().err


def _pooled(tmp_path, *options, first=(0,), second=(1, 2), **second_grid):
    """The study of a 16-unit grid and a 64-unit width joined from two grids (``first``'s seeds
    and ``second``'s), ``second_grid`` overriding the second grid's settings; the exit code."""
    one = write_fake_grid(tmp_path / "h64-a", seeds=first, hidden=64, epochs=12,
                          experiments=MODELS, schedule_factors={"APoc": 1.5})
    settings = {"hidden": 64, "epochs": 12, "experiments": MODELS,
                "schedule_factors": {"APoc": 1.5}, "scores_seed": 1} | second_grid
    two = write_fake_grid(tmp_path / "h64-b", seeds=second, **settings)
    return tables_main(["width", str(_grid(tmp_path, 16)), f"{one}+{two}", *options,
                        "--out", str(tmp_path / "w")]), one, two


@pytest.mark.slow
def test_grids_of_one_width_pool_their_seeds(tmp_path):
    code, one, two = _pooled(tmp_path)
    assert code == 0
    table = pd.read_csv(tmp_path / "w" / "width.csv", dtype={"seeds": str})
    row = table[(table.hidden == 64) & (table.metric == "gesture_edit")].iloc[0]
    runs = pd.concat([run_rows(one)[0], run_rows(two)[0]])       # by hand: seeds 0, 1 and 2
    a, apoc = (runs[runs.variant == v].groupby("fold").gesture_edit.mean() for v in ("A", "APoc"))
    assert a.index.tolist() == list(FOLDS)
    assert row.A_mean == pytest.approx(a.mean(), abs=1e-4)
    assert row.A_std == pytest.approx(a.std(ddof=1), abs=1e-4)
    assert row.APoc_mean == pytest.approx(apoc.mean(), abs=1e-4)
    assert row["diff"] == pytest.approx((apoc - a).mean(), abs=1e-4)
    assert (row.seeds, row.folds, row.A_runs, row.APoc_runs) == ("0 1 2", 8, 24, 24)
    assert (row.A_epochs, row.APoc_epochs) == (12, 18)
    assert row.grids == f"{one}: 0; {two}: 1 2"
    assert set(table[table.hidden == 16].grids) == {f"{tmp_path / 'h16'}: 0"}


@pytest.mark.slow
def test_a_pooled_width_is_the_table_of_one_grid_holding_its_runs(tmp_path):
    """Pooling changes nothing but where the runs lie: the table of the two grids' runs copied
    into one grid is the pooled one."""
    code, one, two = _pooled(tmp_path)
    pooled = pd.read_csv(tmp_path / "w" / "width.csv")
    merged = tmp_path / "merged"
    shutil.copytree(one, merged)
    shutil.copytree(two / "runs", merged / "runs", dirs_exist_ok=True)
    recorded = [json.loads((grid / "grid.json").read_text())["runs"] for grid in (one, two)]
    (merged / "grid.json").write_text(json.dumps({"runs": recorded[0] + recorded[1]}))
    assert tables_main(["width", str(tmp_path / "h16"), str(merged),
                        "--out", str(tmp_path / "m")]) == 0
    alone = pd.read_csv(tmp_path / "m" / "width.csv")
    assert "grids" not in alone.columns and code == 0
    pd.testing.assert_frame_equal(alone, pooled.drop(columns="grids"))


@pytest.mark.slow
def test_one_grid_per_width_writes_no_grids_column(tmp_path):
    small, wide = _grid(tmp_path, 32), _grid(tmp_path, 64, seeds=(0, 1))
    assert tables_main(["width", str(small), str(wide), "--out", str(tmp_path / "w")]) == 0
    columns = pd.read_csv(tmp_path / "w" / "width.csv").columns
    assert "grids" not in columns and columns[-2:].tolist() == ["paper_A", "paper_APoc"]


def test_pooled_grids_of_another_schedule_are_refused_naming_it(tmp_path, capsys):
    code, one, two = _pooled(tmp_path, schedule_factors={"A": 1.5, "APoc": 1.5})
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.count(f"{one}+{two}: runs of one configuration differ") == 1
    assert "revised/bidirectional/A-fixed: " in err and "APoc" not in err
    assert f"run.optim.total 12 ({one}/runs" in err and f"/ 18 ({two}/runs" in err
    assert not (tmp_path / "w").exists()


def test_one_seed_in_two_grids_of_a_width_is_refused_naming_both(tmp_path, capsys):
    code, one, two = _pooled(tmp_path, second=(0, 1))
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"{one} and {two} both hold seed 0 of A-fixed" in err
    assert not (tmp_path / "w").exists()


def test_grids_of_other_widths_in_one_entry_are_refused(tmp_path, capsys):
    code, one, two = _pooled(tmp_path, hidden=32)
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"the grids of one entry are of different widths ({one}: 64, {two}: 32)" in err


def test_pooled_grids_on_other_data_are_refused(tmp_path, capsys):
    one = _grid(tmp_path, 64)
    two = write_fake_grid(tmp_path / "h64-b", seeds=(1,), hidden=64, epochs=12,
                          experiments=MODELS, schedule_factors={"APoc": 1.5})
    for path in two.glob("runs/**/config.json"):
        config = json.loads(path.read_text())
        config["run"]["data"]["preprocessing"]["cutoff_hz"] = 2.0
        path.write_text(json.dumps(config))
    assert tables_main(["width", str(_grid(tmp_path, 16)), f"{one}+{two}",
                        "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert f"the grids differ in their data settings (preprocessing): {one} and {two}" in err


@pytest.mark.slow
def test_seeds_take_each_from_the_grid_that_holds_it(tmp_path):
    code, one, two = _pooled(tmp_path, "--seeds", "0", "2")
    assert code == 0
    table = pd.read_csv(tmp_path / "w" / "width.csv", dtype={"seeds": str})
    wide = table[table.hidden == 64]
    assert set(wide.seeds) == {"0 2"} and set(wide.grids) == {f"{one}: 0; {two}: 2"}
    (tmp_path / "only").mkdir()
    code, one, two = _pooled(tmp_path / "only", "--seeds", "0")      # none from the second
    table = pd.read_csv(tmp_path / "only" / "w" / "width.csv", dtype={"seeds": str})
    assert code == 0 and set(table.seeds) == {"0"} and "grids" not in table.columns


def test_a_grid_of_the_entry_still_training_refuses_the_entry(tmp_path, capsys):
    """Each grid of an entry is checked alone: the second's only seed not finished is its
    one-line error."""
    one = _grid(tmp_path, 64)
    two = write_fake_grid(tmp_path / "h64-b", seeds=(1,), hidden=64, epochs=12,
                          experiments=MODELS, schedule_factors={"APoc": 1.5})
    (two / "runs/revised/bidirectional/A-fixed/seed1/B/finished.json").unlink()
    assert tables_main(["width", str(_grid(tmp_path, 16)), f"{one}+{two}",
                        "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert f"{two}: no seed with every run" in err and "A-fixed 7 of 8 runs finished" in err


@pytest.mark.parametrize("entry", ["{g}+", "+{g}", "{g}++{g}", "{g}+{g}"])
def test_malformed_entries_are_one_line_errors(tmp_path, capsys, entry):
    grid = _grid(tmp_path, 64)
    assert tables_main(["width", str(_grid(tmp_path, 16)), entry.format(g=grid),
                        "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert ("an empty grid name" in err) or (f"{grid} is named twice" in err)
    assert not (tmp_path / "w").exists()


def test_a_folder_whose_name_holds_the_join_is_refused_not_split(tmp_path, capsys):
    _grid(tmp_path, 64), _grid(tmp_path, 32)
    joined = _grid(tmp_path / "x", 128).rename(tmp_path / "h64+h32")
    assert tables_main(["width", str(_grid(tmp_path, 16)), str(joined),
                        "--out", str(tmp_path / "w")]) == 2
    assert "a folder whose name holds '+'" in capsys.readouterr().err


def test_a_missing_grid_of_an_entry_is_named(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    assert tables_main(["width", str(_grid(tmp_path, 16)), f"{grid}+{tmp_path / 'nope'}",
                        "--out", str(tmp_path / "w")]) == 2
    assert f"{tmp_path / 'nope'}: no such folder" in capsys.readouterr().err


@pytest.mark.slow
def test_grid_dir_may_be_a_joined_entry_too(tmp_path):
    code, one, two = _pooled(tmp_path)
    pooled = pd.read_csv(tmp_path / "w" / "width.csv")
    assert tables_main(["width", f"{one}+{two}", str(tmp_path / "h16"),
                        "--out", str(tmp_path / "first")]) == 0
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "first" / "width.csv"), pooled)
