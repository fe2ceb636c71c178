"""The convergence ladders of results/tcn/PLAN_factors.md, section E: ``epochs`` on a TCN grid,
a run's history cut at a shorter length, and ``multitask-tables ladder``."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.plans.ladder import TOO_SHORT, LadderError, ladder_choice
from multitask.grid.cli import main as grid_main
from rnn_seg.convergence import VERDICTS, drop_interval, history_convergence
from rnn_seg.runs.logs import read_log

PILOT = """
preset = "paper"
encoder = "ed-tcn"
data_dir = "{data}"
test_users = ["B"]
seeds = [0]
inner_validation = 1
epochs = {epochs}
plots = "none"
[[experiments]]
variants = ["A"]
annotations = ["original"]
"""
RUN = "runs/original/bidirectional/A-fixed/seed0/B-val-C"
ROOT = Path(__file__).resolve().parents[1]
#: Committed archives of ED-TCN inner runs (200 epochs at a constant rate), and of four LSTM
#: runs (their rate halves from epoch 80).
FACTORS = ROOT / "results/tcn/factors/grids"
LSTM = ROOT / "results/figures/examples-grid"


@pytest.fixture(scope="module")
def pilots(tmp_path_factory, synth_dir) -> dict[int, Path]:
    """One ED-TCN pilot run trained for 18 epochs, and the same run trained for 9 (16 and 18
    are the shortest lengths a ladder judges: ``MIN_POINTS`` epochs in their last fifth)."""
    root = tmp_path_factory.mktemp("ladder")
    grids = {}
    for epochs in (18, 9):
        spec = root / f"pilot-{epochs}.toml"
        spec.write_text(PILOT.format(data=synth_dir, epochs=epochs))
        assert grid_main(["--spec", str(spec), "--out", str(root / f"g{epochs}"),
                          "--workers", "0"]) == 0
        grids[epochs] = root / f"g{epochs}"
    return grids


@pytest.mark.slow
def test_a_constant_rate_runs_first_epochs_do_not_depend_on_its_length(pilots):
    """What the ladder rests on: the longer run's history cut at 9 epochs is the shorter's."""
    long, short = (read_log(pilots[n] / RUN / "history.csv") for n in (18, 9))
    assert len(long) == 18 and len(short) == 9
    pd.testing.assert_series_equal(long["loss_gesture"].iloc[:9], short["loss_gesture"],
                                   rtol=1e-5)


@pytest.mark.slow
def test_ladder_tables_from_pilot_runs_and_their_archive(pilots, tmp_path, capsys):
    out = tmp_path / "ladder"
    assert tables_main(["ladder", str(pilots[18]), "--lengths", "16", "18", "9",
                        "--out", str(out)]) == 0
    runs = pd.read_csv(out / "ladder_runs.csv")
    assert runs.length.tolist() == [9, 16, 18]
    assert runs.verdict.iloc[0] == TOO_SHORT and set(runs.verdict[1:]) <= set(VERDICTS)
    assert runs.fold.unique().tolist() == ["B-val-C"]
    summary = pd.read_csv(out / "ladder.csv")
    counted = summary[["converged", "undecided", "still_falling", "too_short"]].sum(axis=1)
    assert (counted == summary.runs).all() and (summary.runs == 1).all()
    choice = pd.read_csv(out / "ladder_choice.csv")
    assert len(choice) == 1 and choice.length.iloc[0] in (16, 18)
    assert "| ED-TCN | A-fixed, original |" in (out / "ladder.md").read_text()
    assert json.loads((out / "ladder.json").read_text())["lengths"] == [16, 18, 9]
    archive = tmp_path / "archive"
    assert tables_main(["archive", str(pilots[18]), str(archive)]) == 0
    again = tmp_path / "again"
    assert tables_main(["ladder", str(archive), "--lengths", "9", "16", "18",
                        "--out", str(again)]) == 0
    for name in ("ladder_runs.csv", "ladder.csv", "ladder_choice.csv", "ladder.md"):
        assert (again / name).read_text().replace(str(archive), "G") == (
            out / name).read_text().replace(str(pilots[18]), "G")
    capsys.readouterr()
    assert tables_main(["ladder", str(pilots[18]), "--lengths", "19",
                        "--out", str(tmp_path / "beyond")]) == 2
    err = capsys.readouterr().err.strip()
    assert "19" in err and "18" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "beyond").exists()


def test_a_backbone_takes_the_shortest_length_without_a_run_still_falling():
    def summary(falling):
        return pd.DataFrame({"grid": "g", "architecture": "ED-TCN",
                             "length": [200, 300, 400, 600], "still_falling": falling,
                             "too_short": 0, "runs": 8})

    taken = ladder_choice(summary([3, 0, 1, 0])).iloc[0]
    assert (taken.length, taken.still_falling) == (300, 0)
    taken = ladder_choice(summary([3, 2, 1, 1])).iloc[0]
    assert taken.length == 600 and "longest" in taken.reason


def _choice_of(falling, too_short):
    return ladder_choice(pd.DataFrame({"grid": "g", "architecture": "ED-TCN",
                                       "length": [20, 200, 300, 400], "still_falling": falling,
                                       "too_short": too_short, "runs": 8}))


def test_a_length_too_short_to_judge_a_run_is_never_taken():
    taken = _choice_of([0, 0, 1, 0], [8, 0, 0, 0]).iloc[0]
    assert taken.length == 200
    taken = _choice_of([0, 2, 1, 1], [8, 0, 0, 0]).iloc[0]
    assert taken.length == 400 and "longest" in taken.reason
    taken = _choice_of([0, 2, 1, 0], [8, 0, 0, 3]).iloc[0]
    assert taken.length == 300 and "longest" in taken.reason
    with pytest.raises(LadderError, match="too short"):
        _choice_of([0, 0, 0, 0], [8, 8, 8, 8])


def test_a_ladder_of_committed_runs_is_the_convergence_check_of_their_cut_history(tmp_path):
    grid = FACTORS / "T-5hz-k15"
    out = tmp_path / "ladder"
    assert tables_main(["ladder", str(grid), "--lengths", "150", "100", "200",
                        "--out", str(out)]) == 0
    runs = pd.read_csv(out / "ladder_runs.csv")
    row = runs[(runs.fold == "B-val-D") & (runs.length == 150)].iloc[0]
    history = read_log(grid / "runs/original/bidirectional/A-fixed/seed0/B-val-D/history.csv")
    check = history_convergence(history[history.n <= 150], ["gesture"], 150)
    low, high = drop_interval(check["max_loss_drop"], check["max_loss_drop_se"])
    assert row.verdict == check["verdict"]
    assert (row.loss_drop, row.drop_low, row.drop_high) == pytest.approx(
        (check["max_loss_drop"], low, high), rel=1e-5)
    choice = pd.read_csv(out / "ladder_choice.csv").iloc[0]
    judged = runs.groupby("length").verdict.apply(lambda v: (v == "still falling").sum())
    clear = judged[judged == 0]
    assert choice.length == (clear.index.min() if len(clear) else judged.index.max())


def test_two_grids_of_one_backbone_keep_their_own_rows_and_choices(tmp_path):
    grids = [FACTORS / "T-5hz-k15", FACTORS / "T-5hz-k20"]
    out = tmp_path / "ladder"
    assert tables_main(["ladder", *map(str, grids), "--lengths", "100", "200",
                        "--out", str(out)]) == 0
    report = (out / "ladder.md").read_text()
    for grid in grids:
        assert sum(line.startswith(f"| {grid} | ED-TCN |") for line in report.splitlines()) == 2
    assert pd.read_csv(out / "ladder_choice.csv").grid.tolist() == list(map(str, grids))


@pytest.mark.parametrize("case", ["twice", "unfinished", "decaying rate", "all too short",
                                  "a file"])
def test_a_ladder_it_cannot_answer_is_refused_in_one_line(case, tmp_path, capsys):
    grid = FACTORS / "T-5hz-k15"
    run = grid / "runs/original/bidirectional/A-fixed/seed0/B-val-D"
    grids, lengths, named = [grid], ["100"], str(grid)
    if case == "twice":
        grids = [grid, Path(f"{grid}/")]
    elif case == "unfinished":
        grids = [shutil.copytree(grid, tmp_path / "running")]
        (grids[0] / run.relative_to(grid) / "finished.json").unlink()
        named = str(grids[0] / run.relative_to(grid))
    elif case == "decaying rate":
        grids, lengths, named = [LSTM], ["40"], "decays from epoch 80"
    elif case == "all too short":
        lengths = ["5", "10"]
    else:
        grids, named = [run / "history.csv"], f"{run / 'history.csv'}: a file, not a folder"
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("mine")
    capsys.readouterr()
    assert tables_main(["ladder", *map(str, grids), "--lengths", *lengths,
                        "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert named in err and len(err.splitlines()) == 1
    assert [p.name for p in out.iterdir()] == ["mine.txt"]
