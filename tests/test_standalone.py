"""multitask-tables on runs trained one by one: a folder of run folders, no grid.json."""
from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from jigsaws_tools.synth import SynthConfig, write_release
from multitask.evidence.cli import main as tables_main
from multitask.train_cli import main as train_main

TINY = ["--hidden", "8", "--epochs", "2", "--no-plots"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    """Model A on folds B and C and APc on fold B, trained by hand into a folder of the user's
    own layout."""
    root = tmp_path_factory.mktemp("standalone")
    data = write_release(root / "Suturing", SynthConfig(users=("B", "C", "D"), trials_per_user=3))
    for variant, user, out in [("A", "B", "mine/A_B"), ("A", "C", "mine/older/A_C"),
                               ("APc", "B", "mine/APc_B")]:
        assert train_main([*TINY, "--variant", variant, "--data-dir", str(data),
                           "--test-user", user, "--out", str(root / out)]) == 0
    return root / "mine"


@pytest.mark.slow
def test_a_folder_of_runs_is_tabulated_from_their_configs(runs, tmp_path, capsys):
    out = tmp_path / "tables"
    assert tables_main(["runs", str(runs), "--out", str(out)]) == 0
    assert "runs trained one by one" in capsys.readouterr().err
    table = pd.read_csv(out / "runs.csv").set_index("run")
    assert set(table.index) == {"A_B", "older/A_C", "APc_B"}
    assert table.loc["older/A_C", ["variant", "fold", "seed"]].tolist() == ["A", "C", 0]
    assert table.loc["APc_B", "variant"] == "APc" and table.gesture_accuracy.between(0, 100).all()
    summary = pd.read_csv(out / "summary.csv").set_index("variant")
    assert summary.loc["A", "folds"] == 2 and summary.loc["APc", "folds"] == 1
    assert {p.name for p in out.iterdir()} == {"runs.csv", "per_fold.csv", "summary.csv",
                                               "tables.json"}


@pytest.mark.slow
def test_one_run_folder_is_a_table_of_one_run(runs, tmp_path):
    assert tables_main(["runs", str(runs / "A_B"), "--out", str(tmp_path / "one")]) == 0
    assert pd.read_csv(tmp_path / "one" / "runs.csv").run.tolist() == ["."]


@pytest.mark.slow
def test_a_copy_of_a_run_and_an_unfinished_run_are_named(runs, tmp_path, capsys):
    mine = tmp_path / "mine"
    shutil.copytree(runs, mine)
    shutil.copytree(mine / "A_B", mine / "A_B.copy")
    (mine / "APc_B" / "finished.json").unlink()
    assert tables_main(["runs", str(mine), "--out", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and f"not finished: {mine / 'APc_B'}" in err
    assert (f"{mine / 'A_B.copy'}: a second run of the same settings, seed and fold as "
            f"{mine / 'A_B'}") in err
    assert not (tmp_path / "refused").exists()
    assert tables_main(["runs", str(mine), "--out", str(tmp_path / "rest"),
                        "--allow-incomplete"]) == 0
    assert f"left out: {mine / 'A_B.copy'}" in capsys.readouterr().err
    assert pd.read_csv(tmp_path / "rest" / "runs.csv").run.tolist() == ["A_B", "older/A_C"]
