"""The width study (``multitask-tables GRID --widths GRID ...``) on fake grids of several widths."""
from __future__ import annotations

import pandas as pd
import pytest

from tests.fake_grid import FOLDS, write_fake_grid
from multitask.evidence.cli import main as tables_main
from multitask.evidence.collect import run_rows
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
    assert table[table.hidden == 1024].paper_A.notna().all()
    assert table[table.hidden == 32].paper_A.isna().all()


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


@pytest.mark.parametrize("options", [[], ["--seeds", "0"], ["--no-figures"]])
def test_widths_takes_out_alone(tmp_path, capsys, options):
    grid = _grid(tmp_path, 32)
    out = ["--out", str(tmp_path / "w")] if options else []
    with pytest.raises(SystemExit) as exit_:
        tables_main([str(grid), "--widths", str(grid), *out, *options])
    assert exit_.value.code == 2
    assert "--widths needs --out and takes no other option" in capsys.readouterr().err
