"""bench/lea_predictions.py: aligning a reference's released predictions to our labels."""
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[1] / "bench" / "lea_predictions.py"
_spec = importlib.util.spec_from_file_location("lea_predictions", _PATH)
lea = importlib.util.module_from_spec(_spec)
sys.modules["lea_predictions"] = lea
_spec.loader.exec_module(lea)


def _trial_labels(rng, n=437):
    """``[n]`` 30 Hz labels: unlabelled frames first, then segments of 40-120 frames."""
    out = [np.full(7, -1)]
    while sum(map(len, out)) < n:
        out.append(np.full(rng.integers(40, 120), rng.integers(0, 10)))
    return np.concatenate(out)[:n]


def _cell(sequences):
    """A MATLAB cell row ``[1, N]`` of ``[1, T_i]`` rows, as the reference saves lists."""
    out = np.empty((1, len(sequences)), dtype=object)
    for i, s in enumerate(sequences):
        out[0, i] = np.asarray(s)[None, :]
    return out


@pytest.mark.parametrize("stride", [3, 5, 10])
def test_stride_found_also_without_the_last_sample(stride):
    labels = np.repeat(np.arange(12) % 4, 37)
    assert lea.stride_of(labels[::stride], labels, "t") == stride
    assert lea.stride_of(labels[::stride][:-1], labels, "t") == stride


def test_labels_that_match_no_stride_name_the_trial():
    labels = np.repeat(np.arange(12) % 4, 37)
    wrong = labels[::10].copy()
    wrong[3] = 9
    with pytest.raises(lea.UnusableFile, match="Split_2.mat: Suturing_C001"):
        lea.stride_of(wrong, labels, "Split_2.mat: Suturing_C001")


def test_held_predictions_take_the_last_sample_at_or_before_each_frame():
    pred = np.array([0, 1, 2, 3])                 # at labelled frames 0, 10, 20, 30
    assert lea.held(pred, 10, 35, step=6).tolist() == [0, 0, 1, 1, 2, 3]


def test_a_split_is_scored_against_our_labels_at_their_stride(tmp_path):
    from scipy.io import savemat

    rng = np.random.default_rng(0)
    trials = {"Suturing_C001": _trial_labels(rng), "Suturing_C002": _trial_labels(rng)}
    perfect, wrong = [], []
    for labels in trials.values():
        y = labels[labels >= 0][::10]
        perfect.append(y)
        wrong.append((y + 1) % 10)
    savemat(tmp_path / "2.mat", {"P": _cell([perfect[0], wrong[1]]), "Y": _cell(perfect)})
    scored = lea.score_split(tmp_path / "2.mat", list(trials), "C", trials.__getitem__,
                             {"Suturing_C001"})
    assert [t.stride for t in scored] == [10, 10]
    assert [t.in_our_release for t in scored] == [True, False]
    assert scored[0].scores["accuracy"] == 100.0 and scored[1].scores["accuracy"] == 0.0
    assert scored[0].scores_5hz["edit"] == 100.0


def test_a_split_file_with_other_trials_is_refused(tmp_path):
    from scipy.io import savemat

    y = np.zeros(5, dtype=np.int64)
    savemat(tmp_path / "1.mat", {"P": _cell([y]), "Y": _cell([y])})
    with pytest.raises(lea.UnusableFile, match="1 predicted sequences, but its split's test.txt"
                                               " names 2 trials"):
        lea.score_split(tmp_path / "1.mat", ["a", "b"], "B", None, set())


def _scored(user, accuracy, edit):
    scores = dict.fromkeys(lea.METRICS, 50.0) | {"accuracy": accuracy, "edit": edit}
    return lea.ScoredTrial(f"Suturing_{user}001", user, 10, True, scores, scores)


def test_the_comparison_says_which_target_metrics_are_within_the_tolerance():
    ours = {u: dict.fromkeys(lea.METRICS, 50.0) | {"accuracy": 80.0, "edit": 70.0}
            for u in "BC"}
    theirs = [_scored("B", 81.0, 74.0), _scored("C", 82.0, 74.0)]
    rows = {r["metric"]: r for r in lea.comparison(theirs, ours)}
    assert rows["accuracy"]["ours_minus_theirs"] == pytest.approx(-1.5)
    assert rows["accuracy"]["within_1.5"] == "yes" and rows["edit"]["within_1.5"] == "no"
    assert rows["f1@10"]["within_1.5"] == "yes" and rows["f1@50"]["within_1.5"] == ""


def test_a_fold_in_one_side_only_is_named():
    ours = {u: dict.fromkeys(lea.METRICS, 50.0) for u in "BD"}
    with pytest.raises(lea.UnusableFile, match="folds C, D"):
        lea.comparison([_scored("B", 1.0, 1.0), _scored("C", 1.0, 1.0)], ours)


def test_the_csv_is_written_whole_or_not_at_all(tmp_path):
    ours = {u: dict.fromkeys(lea.METRICS, 50.0) for u in "BC"}
    rows = lea.comparison([_scored("B", 50.0, 50.0), _scored("C", 40.0, 40.0)], ours)
    lea.write_csv(rows, tmp_path / "lea.csv")
    lines = (tmp_path / "lea.csv").read_text().splitlines()
    assert lines[0].split(",")[-1] == "within_1.5" and len(lines) == 1 + len(lea.METRICS)
    with pytest.raises(lea.UnusableFile, match="missing/lea.csv: no folder"):
        lea.write_csv(rows, tmp_path / "missing" / "lea.csv")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lea.csv"]


@pytest.mark.parametrize("given", ["", ".", "/", "folder", "missing/lea.csv"])
def test_a_csv_destination_that_names_no_writable_file_is_refused_before_the_scoring(
        tmp_path, monkeypatch, capsys, given):
    """--csv naming no file (empty, ``.``, ``/``), a folder or a file in no folder: one line,
    before the reference is read (here: it does not exist)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder").mkdir()
    assert lea.main(["--reference", "no-checkout", "--ours", "no.csv", "--csv", given]) == 1
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and ("--csv FILE" in error or "no folder" in error)
    assert "no.csv" not in error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"]
