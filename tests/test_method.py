"""``multitask-tables score``: another method's predictions scored as our runs are, checked
before scoring, and paired with archived baselines as ``statistics.paired`` pairs ours."""
from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jigsaws_tools.dataset import DataConfig, load_dataset
from jigsaws_tools.task_definition import SUTURING
from multitask.evidence.cli import main as tables_main
from multitask.evidence.runs.method import _trial_files, method_scores, truth
from multitask.evidence.statistics.paired import ConfigId, Contrast, holm, paired
from multitask.evidence.studies.method import caption, compare, read_baselines
from multitask.grid.archive import ARCHIVE_RECORD
from multitask.grid.spec import Experiment
from rnn_seg.metrics import segmentation_metrics
from tests.fake_grid import write_fake_grid

ROOT = Path(__file__).resolve().parents[1]
GESTURES = np.asarray(SUTURING.gestures)
#: The marker of docs/YOUR_METHOD.md's worked example, which ``test_the_worked_example_runs``
#: runs.
WORKED_EXAMPLE = "<!-- worked example: tests/test_method.py -->"


@pytest.fixture(scope="module")
def trials(synth_dir):
    return truth(DataConfig(str(synth_dir)))


def _frame_labels(trial, rng=None) -> np.ndarray:
    """``[n_frames]`` gesture indices: each frame the true gesture of the last scored sample at or
    before it (the first sample's before it); with ``rng``, a fifth of the segments relabelled."""
    index = np.maximum(np.searchsorted(trial.frames, np.arange(1, trial.n_frames + 1),
                                       side="right") - 1, 0)
    labels = trial.gestures[index]
    if rng is not None:
        starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
        for start in starts[rng.random(len(starts)) < 0.2]:
            labels[start:start + 40] = rng.integers(len(GESTURES))
    return labels


def _write(folder: Path, labels: dict[str, np.ndarray], rate: int, fmt: str) -> Path:
    """Each trial's ``[n_frames]`` labels at ``rate`` Hz (every 30/rate-th frame from the
    first) as ``<trial>.txt`` or ``<trial>.csv`` (frame,gesture)."""
    folder.mkdir(parents=True)
    step = 30 // rate
    for name, frame_labels in labels.items():
        kept = GESTURES[frame_labels[::step]]
        if fmt == "txt":
            (folder / f"{name}.txt").write_text("\n".join(kept) + "\n")
        else:
            pd.DataFrame({"frame": 1 + step * np.arange(len(kept)), "gesture": kept}).to_csv(
                folder / f"{name}.csv", index=False)
    return folder


def _score(folder: Path, synth_dir: Path, rate: float) -> pd.DataFrame:
    return method_scores([folder], DataConfig(str(synth_dir)), rate)[0]


@pytest.mark.slow
def test_per_fold_scores_equal_what_the_metric_code_gives(tmp_path, synth_dir, trials):
    rng = np.random.default_rng(0)
    labels = {t.name: _frame_labels(t, rng) for t in trials}
    scores = _score(_write(tmp_path / "p", labels, 30, "txt"), synth_dir, 30).set_index("fold")
    dataset = load_dataset(DataConfig(str(synth_dir)))
    for user in dataset.users:
        test = dataset.louo_split(user)[1]
        expected = segmentation_metrics([labels[t.name][t.frames - 1] for t in test],
                                        [t.gestures for t in test])
        for metric, value in expected.items():
            assert scores.loc[user, f"gesture_{metric}"] == pytest.approx(value), metric
    assert scores["gesture_accuracy"].lt(100).all()


def test_the_true_labels_score_100(tmp_path, synth_dir, trials):
    scores = _score(_write(tmp_path / "p", {t.name: _frame_labels(t) for t in trials}, 30,
                           "csv"), synth_dir, 30)
    for metric in ("accuracy", "edit", "f1@10", "f1@25", "f1@50"):
        assert scores[f"gesture_{metric}"].eq(100).all(), metric


@pytest.mark.slow
def test_both_formats_and_both_rates_score_alike(tmp_path, synth_dir, trials):
    rng = np.random.default_rng(1)
    at_5hz = {t.name: np.repeat(_frame_labels(t, rng)[::6], 6)[:t.n_frames] for t in trials}
    scores = [_score(_write(tmp_path / f"{fmt}{rate}", at_5hz, rate, fmt), synth_dir, rate)
              for fmt in ("txt", "csv") for rate in (30, 5)]
    for other in scores[1:]:
        pd.testing.assert_frame_equal(scores[0], other)


def _refused(tmp_path, capsys, folder: Path | list[Path], synth_dir: Path, *extra: str) -> str:
    out = tmp_path / "tables"
    folders = folder if isinstance(folder, list) else [folder]
    code = tables_main(["score", *map(str, folders), "--data-dir", str(synth_dir), "--rate",
                        "30", *extra, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists(), err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.slow
def test_a_wrong_folder_is_refused_naming_the_trial(tmp_path, capsys, synth_dir, trials):
    good = _write(tmp_path / "good", {t.name: _frame_labels(t) for t in trials}, 30, "txt")
    first = trials[0]

    def broken(name: str) -> Path:
        folder = tmp_path / name
        shutil.copytree(good, folder)
        return folder

    short = broken("short")
    (short / f"{first.name}.txt").write_text("G1\n" * (first.n_frames - 5))
    err = _refused(tmp_path, capsys, short, synth_dir)
    assert first.name in err and f"{first.n_frames - 5} lines" in err
    assert f"expected {first.n_frames}" in err

    unknown = broken("unknown")
    lines = (unknown / f"{first.name}.txt").read_text().splitlines()
    lines[6] = "G99"
    (unknown / f"{first.name}.txt").write_text("\n".join(lines) + "\n")
    err = _refused(tmp_path, capsys, unknown, synth_dir)
    assert f"{first.name}.txt:7:" in err and "'G99'" in err

    missing = broken("missing")
    (missing / f"{first.name}.txt").unlink()
    assert first.name in _refused(tmp_path, capsys, missing, synth_dir)

    extra = broken("extra")
    (extra / "Suturing_Z001.txt").write_text("G1\n")
    assert "Suturing_Z001" in _refused(tmp_path, capsys, extra, synth_dir)

    other = broken("other")
    (other / "Knot_Tying_B001.txt").write_text("G1\n")
    assert "another task" in _refused(tmp_path, capsys, other, synth_dir)

    assert "divisor" in _refused(tmp_path, capsys, good, synth_dir, "--rate", "7")


@pytest.mark.slow
def test_files_as_other_tools_write_them_are_read_or_refused_in_one_line(tmp_path, capsys,
                                                                       synth_dir, trials):
    """A byte-order mark and Windows line endings are read; a byte that is not UTF-8, an empty
    line, a file of another rate, MS-TCN's results layout and a file given as the folder are
    refused naming file, line and value (or the rate whose length the file has)."""
    rng = np.random.default_rng(3)
    labels = {t.name: _frame_labels(t, rng) for t in trials}
    good = _write(tmp_path / "good", labels, 30, "txt")
    first = trials[0]
    windows = shutil.copytree(good, tmp_path / "windows")
    for path in windows.iterdir():
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes().replace(b"\n", b"\r\n"))
    windows_csv = _write(tmp_path / "windows_csv", labels, 30, "csv")
    for path in windows_csv.iterdir():
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    for folder in (windows, windows_csv):
        pd.testing.assert_frame_equal(_score(folder, synth_dir, 30), _score(good, synth_dir, 30))

    def broken(name: str, content: bytes) -> Path:
        folder = shutil.copytree(good, tmp_path / name)
        (folder / f"{first.name}.txt").write_bytes(content)
        return folder

    lines = (good / f"{first.name}.txt").read_bytes().splitlines(keepends=True)
    latin = broken("latin", b"".join(lines[:3] + [b"G1\xe9\n"] + lines[4:]))
    err = _refused(tmp_path, capsys, latin, synth_dir)
    assert f"{first.name}.txt:4:" in err and "xe9" in err and "UTF-8" in err
    blank = broken("blank", b"".join(lines) + b"\n")
    err = _refused(tmp_path, capsys, blank, synth_dir)
    assert f"{first.name}.txt:{len(lines) + 1}:" in err and "empty" in err
    at_5hz = broken("at_5hz", b"".join(lines[::6]))
    err = _refused(tmp_path, capsys, at_5hz, synth_dir)
    assert f"{len(lines[::6])} lines, expected {first.n_frames}" in err and "--rate 5:" in err
    ms_tcn = broken("ms_tcn", b"### Frame level recognition: ###\n" + b" ".join(
        line.strip() for line in lines))
    err = _refused(tmp_path, capsys, ms_tcn, synth_dir)
    assert f"{first.name}.txt:1:" in err and "MS-TCN" in err
    err = _refused(tmp_path, capsys, good / f"{first.name}.txt", synth_dir)
    assert "not a folder" in err


@pytest.mark.slow
def test_seeds_and_files_that_disagree_are_refused_naming_them(tmp_path, capsys, synth_dir,
                                                               trials):
    """One folder given twice (or by a second path), progress predictions in some files or some
    seeds only, a trial's name in another case and a CSV column named twice: each one line."""
    labels = {t.name: _frame_labels(t) for t in trials}
    gestures = _write(tmp_path / "gestures", labels, 30, "csv")
    first = trials[0]
    err = _refused(tmp_path, capsys, [gestures, gestures], synth_dir)
    assert "given twice" in err and "one folder per seed" in err
    (tmp_path / "link").symlink_to(gestures)
    err = _refused(tmp_path, capsys, [gestures, tmp_path / "link"], synth_dir)
    assert f"{tmp_path / 'link'}: given twice (as {gestures})" in err

    both = shutil.copytree(gestures, tmp_path / "both")
    for path in both.iterdir():
        table = pd.read_csv(path)
        path.write_text(table.assign(progress=SUTURING.stage_names[0]).to_csv(index=False))
    assert set(_score(both, synth_dir, 30).columns) > set(_score(gestures, synth_dir, 30).columns)
    err = _refused(tmp_path, capsys, [both, gestures], synth_dir)
    assert f"{gestures}: no progress predictions, which {both} has" in err

    some = shutil.copytree(both, tmp_path / "some")
    shutil.copy(gestures / f"{first.name}.csv", some / f"{first.name}.csv")
    err = _refused(tmp_path, capsys, some, synth_dir)
    assert f"{first.name}.csv: no progress column" in err and "every file or in none" in err

    cased = shutil.copytree(gestures, tmp_path / "cased")
    (cased / f"{first.name}.csv").rename(cased / f"{first.name.lower()}.csv")
    err = _refused(tmp_path, capsys, cased, synth_dir)
    assert f"the release spells it {first.name}" in err and "another task" not in err
    (cased / f"{first.name.lower()}.csv").rename(cased / "suturing_Z001.csv")  # no such trial
    err = _refused(tmp_path, capsys, cased, synth_dir)
    assert "the release spells its task Suturing" in err and "another task" not in err
    (cased / "suturing_Z001.csv").rename(cased / f"{first.name}.CSV")
    assert "extension must be lower case" in _refused(tmp_path, capsys, cased, synth_dir)

    twice = shutil.copytree(gestures, tmp_path / "twice")
    path = twice / f"{first.name}.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(f"{line},{line.split(',')[1]}" if k else "frame,gesture,gesture"
                               for k, line in enumerate(lines)) + "\n")
    err = _refused(tmp_path, capsys, twice, synth_dir)
    assert f"{first.name}.csv:1: column 'gesture' twice" in err
    for header, named in (("frame,gesture,Gesture", "'Gesture'"),
                          ("frame,gesture, progress", "' progress'"),
                          ("frame, gesture", "' gesture'")):
        path.write_text("\n".join([header] + lines[1:]) + "\n")
        err = _refused(tmp_path, capsys, twice, synth_dir)
        assert f"{first.name}.csv:1: column {named}" in err and "names are exact" in err, header
    path.write_text("\n".join(["frame,gesture,,"] + [f"{l},," for l in lines[1:]]) + "\n")
    pd.testing.assert_frame_equal(_score(twice, synth_dir, 30), _score(gestures, synth_dir, 30))


@pytest.fixture(scope="module")
def baselines(tmp_path_factory, synth_dir) -> dict[str, Path]:
    """Scores archives of model A (an LSTM grid) and MS-TCN's A on the synthetic release's
    trials, without training (``fake_grid``)."""
    root = tmp_path_factory.mktemp("baselines")
    experiments = (Experiment(("A", "APc"), ("fixed",), ("revised",), ("bidirectional",)),)
    grids = {"lstm": write_fake_grid(root / "lstm", seeds=(0, 1, 2), experiments=experiments),
             "ms-tcn": write_fake_grid(root / "ms-tcn", seeds=(0, 1), encoder="ms-tcn",
                                       experiments=experiments[:1], scores_seed=1)}
    folds: dict[str, list[str]] = {}
    for trial in truth(DataConfig(str(synth_dir))):
        folds.setdefault(trial.user, []).append(trial.name)
    for grid in grids.values():                  # as archives: test trials, no predictions
        for predictions in grid.glob("runs/**/eval"):
            shutil.rmtree(predictions)
        (grid / ARCHIVE_RECORD).write_text(json.dumps({"test_trials": folds}))
    return grids


@pytest.mark.slow
def test_the_pairing_is_statistics_paired_on_the_same_numbers(tmp_path, synth_dir, trials,
                                                              baselines):
    rng = np.random.default_rng(2)
    folders = [_write(tmp_path / f"seed{k}", {t.name: _frame_labels(t, rng) for t in trials},
                      30, "txt") for k in range(2)]
    scores, folds = method_scores(folders, DataConfig(str(synth_dir)), 30)
    against = [(baselines["lstm"], []), (baselines["ms-tcn"], [ConfigId("A")])]
    chosen, runs = read_baselines(against, "revised", folds, 5.0)
    assert [b.name for b in chosen] == ["LSTM-16 A-fixed", "LSTM-16 APc-fixed",
                                        "MS-TCN A-fixed"]
    metrics = ["gesture_accuracy", "gesture_edit"]
    table = compare(scores, "M", chosen, runs, metrics)
    assert len(table) == 6
    np.testing.assert_allclose(table.p_holm, holm(table.p_value))
    for row, baseline in zip(table.itertuples(), chosen * 2):
        side = runs[runs.grid == str(baseline.grid)]
        mine = scores.assign(variant="M", weighting="fixed", annotations="revised",
                             direction="bidirectional")
        result = paired(pd.concat([mine, side], ignore_index=True),
                        Contrast(ConfigId("M"), baseline.config), row.metric)
        assert (row.diff, row.ci_low, row.ci_high, row.p_value) == pytest.approx(
            (result.mean, *result.ci, result.p_value))
        assert row.folds == " ".join(result.folds) and row.baseline_seeds == result.seeds[1]


@pytest.mark.slow
def test_baselines_of_two_grids_alike_are_named_apart_and_an_unreachable_family_said(
        tmp_path, synth_dir, trials, baselines):
    """Two grids of one architecture (results/grid and results/reference/grid) give rows and
    caption entries that tell them apart; a call of more comparisons than the folds' smallest p
    can carry through Holm says that no verdict but 'no difference detected' is possible."""
    rng = np.random.default_rng(4)
    folder = _write(tmp_path / "seed0", {t.name: _frame_labels(t, rng) for t in trials}, 30,
                    "txt")
    scores, folds = method_scores([folder], DataConfig(str(synth_dir)), 30)
    twin = shutil.copytree(baselines["lstm"], tmp_path / "twin")
    against = [(baselines["lstm"], [ConfigId("A"), ConfigId("APc")]), (twin, [ConfigId("A")])]
    chosen, runs = read_baselines(against, "revised", folds, 5.0)
    assert [b.name for b in chosen] == [f"LSTM-16 A-fixed ({baselines['lstm']})",
                                        "LSTM-16 APc-fixed", f"LSTM-16 A-fixed ({twin})"]
    few = compare(scores, "M", chosen, runs, ["gesture_accuracy", "gesture_edit"])
    assert "whatever the data" not in caption(few, "M", "revised", "Suturing")
    many = compare(scores, "M", chosen, runs, ["gesture_accuracy", "gesture_edit",
                                               "gesture_f1@10"])
    text = caption(many, "M", "revised", "Suturing")
    assert "With 8 folds no p Holm-adjusted over 9 comparisons can fall below 0.070" in text
    assert "at most 6 comparisons" in text and (many.p_holm > 0.05).all()


def test_out_inside_a_prediction_folder_is_refused_before_anything_is_read(tmp_path, capsys):
    predictions = tmp_path / "seed0"
    predictions.mkdir()
    for out in (predictions, predictions / "tables"):
        code = tables_main(["score", str(predictions), "--rate", "30", "--synthetic",
                            "--out", str(out)])
        err = capsys.readouterr().err
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert f"--out {out}: inside the prediction folder {predictions}" in err
    assert list(predictions.iterdir()) == []


def test_a_folder_where_a_prediction_file_should_be_is_named(tmp_path):
    (tmp_path / "Suturing_B001.txt").mkdir()
    with pytest.raises(ValueError, match=r"Suturing_B001\.txt: a folder \(give"):
        _trial_files(tmp_path, {"Suturing_B001"}, SUTURING)


def test_a_grid_tested_on_other_trials_is_refused(tmp_path, synth_dir, baselines):
    folds = {"B": ["Suturing_B001"]}
    with pytest.raises(ValueError, match="fold B was tested on"):
        read_baselines([(baselines["lstm"], [])], "revised", folds, 5.0)


def test_a_grid_scored_at_other_samples_is_refused(tmp_path, trials, baselines):
    """A 3 Hz model's scores are not those of the 5 Hz samples the method is scored at."""
    grid = shutil.copytree(baselines["ms-tcn"], tmp_path / "ms-tcn-3hz")
    configs = sorted(grid.glob("runs/**/config.json"))
    for config in configs:
        record = json.loads(config.read_text())
        record["run"]["data"]["preprocessing"]["resample_factor"] = 10
        config.write_text(json.dumps(record))
    folds: dict[str, list[str]] = {}
    for trial in trials:
        folds.setdefault(trial.user, []).append(trial.name)
    read_baselines([(baselines["ms-tcn"], [])], "revised", folds, 5.0)
    with pytest.raises(ValueError, match=rf"{configs[0].parent} was scored at its 3 Hz samples, the "
                                         r"predictions are scored at 5 Hz"):
        read_baselines([(grid, [])], "revised", folds, 5.0)


@pytest.mark.slow
def test_against_names_a_folder_that_is_no_grid_and_a_baseline_named_twice(
        tmp_path, capsys, synth_dir, trials, baselines):
    good = _write(tmp_path / "good", {t.name: _frame_labels(t) for t in trials}, 30, "txt")
    lstm = baselines["lstm"]
    err = _refused(tmp_path, capsys, good, synth_dir, "--against", str(lstm.parent))
    assert "not a grid folder or scores archive" in err and str(lstm.parent) in err
    err = _refused(tmp_path, capsys, good, synth_dir, "--against", str(tmp_path / "none"))
    assert "no such folder" in err
    err = _refused(tmp_path, capsys, good, synth_dir, "--against", f"{lstm}:A-fixed", str(lstm))
    assert "A-fixed named twice" in err
    out = tmp_path / "tables"
    assert tables_main(["score", str(good), "--data-dir", str(synth_dir), "--rate", "30",
                        "--against", f"{lstm}:A-fixed", "--out", str(out)]) == 0
    assert "mean over its evaluation points" in (out / "score.md").read_text()
    assert "note:" not in capsys.readouterr().err          # no release: nothing to note
    release = tmp_path / "release"                          # a release's layout and manifest
    shutil.copytree(good, release / "revised" / "bidirectional" / "A-fixed" / "seed0")
    (release / "release.json").write_text(json.dumps({"written_by": "multitask-tables",
                                                      "grid": "results/reference/grid"}))
    assert tables_main(["score", str(release / "revised" / "bidirectional" / "A-fixed" / "seed0"),
                        "--data-dir", str(synth_dir), "--rate", "30", "--out", str(out)]) == 0
    printed = capsys.readouterr()
    notes = [line for line in printed.err.splitlines() if line.startswith("note:")]
    assert "| gesture_accuracy | 100.00 |" in printed.out     # without --against: the summary
    assert len(notes) == 1 and "results/reference/grid" in notes[0]
    assert "last evaluation point" in notes[0] and "labels" not in notes[0]
    assert tables_main(["score", str(release / "revised" / "bidirectional" / "A-fixed" / "seed0"),
                        "--data-dir", str(synth_dir), "--rate", "30", "--annotations",
                        "original", "--out", str(out)]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note:")]
    assert "trained on revised labels, scored on original labels" in notes[0]


def _worked_example() -> list[str]:
    """The commands of docs/YOUR_METHOD.md's worked example, continuation lines joined."""
    text = (ROOT / "docs" / "YOUR_METHOD.md").read_text()
    block = text.split(WORKED_EXAMPLE, 1)[1].split("```bash\n", 1)[1].split("```", 1)[0]
    return [line for line in re.sub(r"\\\n\s*", "", block).splitlines() if line.strip()]


@pytest.mark.slow
def test_the_worked_example_runs(tmp_path, synth_dir, baselines):
    """The documented commands, on the synthetic release with archives of A and MS-TCN's A in
    place of results/grid and results/tcn/ms-tcn: a program that imports nothing of ours writes
    the predictions, one command scores and compares them."""
    source = (ROOT / "examples" / "foreign_method.py").read_text()
    assert not re.search(r"^\s*(from|import)\s+(jigsaws_tools|rnn_seg|baseline|multitask)",
                         source, re.M)
    places = {"/path/to/Suturing": str(synth_dir), "results/grid": str(baselines["lstm"]),
              "results/tcn/ms-tcn": str(baselines["ms-tcn"])}
    printed = ""
    for line in _worked_example():
        for documented, here in places.items():
            line = line.replace(documented, here)
        words = shlex.split(line)
        if words[0] == "python":
            words = [sys.executable, str(ROOT / words[1]), *words[2:]]
        else:
            script = "import sys; from multitask.evidence.cli import main; sys.exit(main())"
            words = [sys.executable, "-c", script, *words[1:]]
        result = subprocess.run(words, cwd=tmp_path, capture_output=True, text=True,
                                timeout=600, env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert result.returncode == 0, f"{line}\n{result.stderr}"
        printed += result.stdout
    assert "LSTM-16 A-fixed" in printed and "MS-TCN A-fixed" in printed
    table = pd.read_csv(tmp_path / "my_method" / "tables" / "score.csv")
    assert set(table.baseline) == {"LSTM-16 A-fixed", "MS-TCN A-fixed"}
