"""The width study (``multitask-tables GRID --widths GRID ...``) on fake grids of several widths."""
from __future__ import annotations

import json

import pandas as pd
import pytest

from tests.fake_grid import FOLDS, write_fake_grid
from multitask.evidence.cli import main as tables_main
from multitask.evidence.collect import run_rows
from multitask.evidence.paper_results import TABLE_1
from multitask.grid.spec import Experiment

MODELS = (Experiment(variants=("A",)), Experiment(variants=("APoc",), weightings=("gradnorm",)))


def _grid(root, hidden, seeds=(0,), epochs=12):
    return write_fake_grid(root / f"h{hidden}", seeds=seeds, hidden=hidden, epochs=epochs,
                           experiments=MODELS, schedule_factors={"APoc": 1.5})


def _fold_means(grid, variant, metric):
    runs, _ = run_rows(grid)
    return runs[runs.variant == variant].groupby("fold")[metric].mean()


def test_one_row_per_width_and_metric_from_each_grids_runs(tmp_path, capsys):
    small, paper = _grid(tmp_path, 32), _grid(tmp_path, 1024, seeds=(0, 1))
    assert tables_main([str(paper), "--widths", str(small), "--out", str(tmp_path / "w")]) == 0
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
    assert tables_main([str(grids[0]), "--widths", *map(str, grids[1:]),
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
    assert tables_main([str(grid), "--widths", str(_grid(tmp_path, 16)),
                        "--out", str(tmp_path / "w")]) == 0
    table = pd.read_csv(tmp_path / "w" / "width.csv", dtype={"seeds": str})
    assert set(table[table.hidden == 64].seeds) == {"0"}


def test_two_grids_of_one_width_are_a_one_line_error(tmp_path, capsys):
    grid = _grid(tmp_path, 32)
    assert tables_main([str(grid), "--widths", str(grid), "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "one grid per width, got widths [32, 32]" in err and "Traceback" not in err
    assert not (tmp_path / "w").exists()


def test_seeds_restrict_every_grid(tmp_path):
    small, paper = _grid(tmp_path, 32, seeds=(0, 1)), _grid(tmp_path, 1024, seeds=(0, 1))
    assert tables_main([str(small), "--widths", str(paper), "--seeds", "1",
                        "--out", str(tmp_path / "w")]) == 0
    table = pd.read_csv(tmp_path / "w" / "width.csv", dtype={"seeds": str})
    assert set(table.seeds) == {"1"} and set(table.A_runs) == {len(FOLDS)}


def test_a_grid_without_a_finished_seed_names_what_it_lacks(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    for fold in FOLDS[3:]:
        (grid / f"runs/revised/bidirectional/APoc-gradnorm/seed0/{fold}/finished.json").unlink()
    assert tables_main([str(_grid(tmp_path, 16)), "--widths", str(grid),
                        "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "seed 0: APoc-gradnorm 3 of 8 runs finished" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "w").exists()


def test_a_run_without_usable_metrics_is_one_line_naming_it(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    metrics = grid / "runs/revised/bidirectional/A-fixed/seed0/D/metrics.json"
    metrics.write_text("{")
    assert tables_main([str(_grid(tmp_path, 16)), "--widths", str(grid),
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
    assert tables_main([str(_grid(tmp_path, 16)), "--widths", str(grid),
                        "--out", str(tmp_path / "w")]) == 2
    assert "the grids differ in their folds" in capsys.readouterr().err


def test_grids_on_other_data_settings_are_refused(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    for path in grid.glob("runs/**/config.json"):
        config = json.loads(path.read_text())
        config["run"]["data"]["preprocessing"]["cutoff_hz"] = 2.0
        path.write_text(json.dumps(config))
    assert tables_main([str(_grid(tmp_path, 16)), "--widths", str(grid),
                        "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "the grids differ in their data settings (preprocessing)" in err


def test_seeds_no_grid_has_are_named(tmp_path, capsys):
    grid = _grid(tmp_path, 64)
    assert tables_main([str(_grid(tmp_path, 16)), "--widths", str(grid), "--seeds", "5",
                        "--out", str(tmp_path / "w")]) == 2
    assert "no run of A-fixed or APoc-gradnorm of seed(s) 5" in capsys.readouterr().err


@pytest.mark.parametrize("options", [[], ["--allow-incomplete"], ["--no-figures"]])
def test_widths_takes_out_alone(tmp_path, capsys, options):
    grid = _grid(tmp_path, 32)
    out = ["--out", str(tmp_path / "w")] if options else []
    with pytest.raises(SystemExit) as exit_:
        tables_main([str(grid), "--widths", str(grid), *out, *options])
    assert exit_.value.code == 2
    assert "--widths needs --out and takes no other option" in capsys.readouterr().err
