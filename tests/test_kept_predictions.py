"""Archives that keep predictions: each run's predicted labels (and APr's output), never the true
ones; figures drawn from a run folder and from its archive alike; tables that regenerate
identically with the data elsewhere or absent; an archive without predictions still tabulates."""
from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.grid.archive import ARCHIVE_RECORD, archive_grid
from multitask.grid.cli import main as grid_main
from multitask.grid.kept_predictions import (FILE, VALUE_SCALE, kept_record, prediction_files,
                                             read_kept_predictions)
from rnn_seg.runs.folder import RunFolderError

SPEC = """
preset = "quick"
data_dir = "{data}"
test_users = ["B"]
seeds = [0]
hidden = 8
epochs = 2
plots = "none"

[[experiments]]
variants = ["A", "APr", "APc", "APoc"]
"""
#: The files of a table folder that list its files (they differ when the figures do).
LISTS = ("tables.json",)


@pytest.fixture(scope="module")
def trained(tmp_path_factory, synth_dir) -> tuple[Path, Path, Path]:
    """``(grid, its archive, its data)``: four runs (A, APr, APc, APoc) on fold B of a copy of
    the synthetic release, which the tests may move."""
    root = tmp_path_factory.mktemp("kept")
    data = shutil.copytree(synth_dir, root / "data" / "Suturing")
    spec = root / "spec.toml"
    spec.write_text(SPEC.format(data=data))
    grid, archive = root / "grid", root / "archive"
    assert grid_main(["--spec", str(spec), "--out", str(grid), "--workers", "0"]) == 0
    assert tables_main(["archive", str(grid), str(archive)]) == 0
    return grid, archive, data


def _runs(folder: Path) -> list[Path]:
    return sorted(p.parent for p in folder.glob("runs/*/*/*/*/*/finished.json"))


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name not in LISTS}


def _tables(grid: Path, out: Path, *options: str) -> dict[str, bytes]:
    assert tables_main(["paper", str(grid), "--out", str(out), *options]) == 0
    return _files(out)


@pytest.mark.slow
def test_an_archive_keeps_the_predicted_labels_and_never_the_true_ones(trained):
    grid, archive, _ = trained
    for run in _runs(grid):
        kept_file = archive / run.relative_to(grid) / FILE
        text = kept_file.read_text()
        assert "_true" not in text and "frame" not in text and "time" not in text
        from_run, from_archive = read_kept_predictions(run), read_kept_predictions(kept_file.parent)
        assert from_archive.classes == from_run.classes and from_archive.trials.keys() == \
            from_run.trials.keys() == prediction_files(run).keys()
        for name, path in prediction_files(run).items():
            table = pd.read_csv(path)
            kept = from_archive.trials[name]
            for task, names in from_archive.classes.items():       # samples 0..T-1 in order
                assert [names[k] for k in kept.labels[task]] == table[task].tolist()
                assert kept.labels[task].dtype == np.int64
                np.testing.assert_array_equal(kept.labels[task], from_run.trials[name].labels[task])
            if "progress_value" in table:
                np.testing.assert_allclose(kept.values["progress"], table.progress_value,
                                           atol=0.5 / VALUE_SCALE + 1e-9)
                np.testing.assert_array_equal(kept.values["progress"],
                                              from_run.trials[name].values["progress"])
            else:
                assert kept.values == {}
    sizes = [(archive / run.relative_to(grid) / FILE).stat().st_size for run in _runs(grid)]
    assert max(sizes) < 10_000                   # a few hundred 5 Hz samples a trial, 5 trials


@pytest.mark.slow
def test_figures_from_a_run_folder_and_from_its_archive_are_identical(trained, tmp_path):
    from tests.pdf_pages import read_pdf_page

    grid, archive, _ = trained
    drawn = {folder: _tables(folder, tmp_path / folder.name) for folder in (grid, archive)}
    assert drawn[grid] == drawn[archive]
    examples = [name for name in drawn[grid] if "_example." in name]
    assert len(examples) == 4                       # segmentation and progress, PNG and PDF
    for pdf in (tmp_path / archive.name / "figures").glob("*.pdf"):
        assert "Type3" not in read_pdf_page(pdf).font_subtypes, pdf.name


@pytest.mark.slow
def test_tables_regenerate_identically_with_the_data_elsewhere_or_absent(trained, tmp_path,
                                                                        capsys):
    grid, archive, data = trained
    here = _tables(archive, tmp_path / "here")
    assert (pd.read_csv(tmp_path / "here" / "table1.csv").model == "Time only (t/T)").sum() == 4
    moved = data.parent.parent / "moved"
    data.parent.rename(moved)
    try:
        capsys.readouterr()
        absent = _tables(archive, tmp_path / "absent")
        notes = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note")]
        assert len(notes) == 1 and "no example-trial figures" in notes[0] \
            and str(data) in notes[0]
        assert absent == {name: text for name, text in here.items() if "_example." not in name}
        again = _tables(archive, tmp_path / "here")       # over the earlier output, no data
        assert "left as they were" in capsys.readouterr().err
        assert again == here                               # its example figures and manifest too
        elsewhere = _tables(archive, tmp_path / "elsewhere", "--data-dir",
                            str(moved / "Suturing"))
        assert elsewhere == here
    finally:
        moved.rename(data.parent)


@pytest.mark.slow
def test_an_archive_without_predictions_or_time_only_scores_still_tabulates(trained, tmp_path,
                                                                           capsys):
    grid, archive, data = trained
    old = shutil.copytree(archive, tmp_path / "old")
    for kept in old.glob(f"runs/*/*/*/*/*/{FILE}"):
        kept.unlink()
    record = json.loads((old / ARCHIVE_RECORD).read_text())
    del record["time_only"]
    (old / ARCHIVE_RECORD).write_text(json.dumps(record))
    full = _tables(archive, tmp_path / "full")
    capsys.readouterr()
    tables = _tables(old, tmp_path / "tables")          # the time-only rows from the data
    assert "kept its predictions" in capsys.readouterr().err
    assert tables == {name: text for name, text in full.items() if "_example." not in name}
    data.rename(data.parent / "away")                     # no archived scores, no data: a note
    try:
        assert tables_main(["paper", str(old), "--out", str(tmp_path / "bare")]) == 0
        assert "no time-only progress row in table1" in capsys.readouterr().err
        assert not (pd.read_csv(tmp_path / "bare" / "table1.csv").model == "Time only (t/T)").any()
    finally:
        (data.parent / "away").rename(data)


@pytest.mark.slow
def test_an_archive_of_an_archive_keeps_its_predictions_and_scores_without_the_data(
        trained, tmp_path, capsys):
    grid, archive, data = trained
    copy = shutil.copytree(archive, tmp_path / "copy")
    data.rename(data.parent / "away")
    try:
        assert archive_grid(copy, tmp_path / "again") == (4, 4)
    finally:
        (data.parent / "away").rename(data)
    assert "note" not in capsys.readouterr().err
    for run in _runs(archive):
        relative = run.relative_to(archive)
        assert (tmp_path / "again" / relative / FILE).read_bytes() == (run / FILE).read_bytes()
    again = json.loads((tmp_path / "again" / ARCHIVE_RECORD).read_text())
    assert again["time_only"] == json.loads((archive / ARCHIVE_RECORD).read_text())["time_only"]
    assert again["source"] == str(grid.resolve())           # the grid it was trained in, kept
    rewritten = archive_grid(grid, archive)                 # its own archive again: unchanged
    assert rewritten == (4, 4) and all(
        (run / FILE).read_bytes() == (tmp_path / "again" / run.relative_to(archive) / FILE)
        .read_bytes() for run in _runs(archive))


def test_predictions_of_earlier_versions_and_damaged_records_are_read_or_named(tmp_path):
    """A CSV of an earlier version (class indices in ``<task>_pred``, no ``time_s``) is kept
    alike; a damaged record and a CSV of an unknown class are errors naming the file."""
    from tests.fake_grid import write_fake_run
    from multitask.grid.spec import RunKey

    run = write_fake_run(tmp_path / "run", RunKey("revised", "bidirectional", "APc", "fixed", 0,
                                                  "B"), {})
    predictions = run / "eval" / "epoch0012" / "predictions"
    predictions.mkdir(parents=True)
    pd.DataFrame({"frame": [1, 7, 13], "gesture_true": [0, 2, 2], "gesture_pred": [0, 1, 2],
                  "progress_true": [0, 0, 1], "progress_pred": [0, 1, 1]}
                 ).to_csv(predictions / "Suturing_B001.csv", index=False)
    kept = read_kept_predictions(run)
    assert kept.evaluation == "epoch0012"
    assert kept.trials["Suturing_B001"].labels["gesture"].tolist() == [0, 1, 2]
    assert kept.trials["Suturing_B001"].labels["progress"].tolist() == [0, 1, 1]
    record = kept_record(run)
    record["trials"]["Suturing_B001"]["samples"] = 4
    (run / FILE).write_text(json.dumps(record))
    with pytest.raises(RunFolderError, match=rf"{FILE}: damaged kept predictions"):
        read_kept_predictions(run)
    (run / FILE).unlink()
    pd.DataFrame({"sample": [0, 1], "gesture": ["G1", "G99"], "progress": ["reach", "reach"]}
                 ).to_csv(predictions / "Suturing_B001.csv", index=False)
    with pytest.raises(RunFolderError, match=r"Suturing_B001\.csv: gesture: 'G99'"):
        read_kept_predictions(run)


@pytest.mark.slow
def test_a_release_writes_each_configuration_and_seed_per_frame_as_score_reads_it(
        trained, tmp_path, capsys, monkeypatch):
    from dataclasses import replace

    from multitask.evidence.runs.method import Layout, read_folder, truth
    from multitask.models.run_record import read_run_record

    grid, archive, data = trained
    out = tmp_path / "release"
    assert tables_main(["release", str(archive), "--out", str(out)]) == 0
    runs = _runs(archive)
    for run in runs:
        kept = read_kept_predictions(run)
        record = read_run_record(run)
        folder = out / run.relative_to(archive / "runs").parent
        trials = [t for t in truth(replace(record.config.data, data_dir=str(data)))
                  if t.name in kept.trials]
        read = read_folder(folder, trials, record.config.data.task, Layout(30, 30))
        for trial in trials:
            assert np.array_equal(read[trial.name].gestures, kept.trials[trial.name]
                                  .labels["gesture"])
            text = (folder / f"{trial.name}.csv").read_text()
            assert "true" not in text and len(text.splitlines()) == trial.n_frames + 1
    assert "README.md" in {p.name for p in out.iterdir()}
    monkeypatch.chdir(archive.parent)                       # the grid named relative too
    assert tables_main(["release", archive.name, "--out", str(tmp_path / "A"),
                        "--configs", "A-fixed"]) == 0
    assert [p.name for p in (tmp_path / "A" / "revised" / "bidirectional").iterdir()] == [
        "A-fixed"]


@pytest.mark.slow
def test_a_release_refuses_a_configuration_the_grid_lacks_and_an_archive_without_predictions(
        trained, tmp_path, capsys):
    grid, archive, data = trained
    assert tables_main(["release", str(archive), "--out", str(tmp_path / "x"),
                        "--configs", "APoc-gradnorm"]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "APoc-gradnorm" in error
    old = shutil.copytree(archive, tmp_path / "old")
    for path in old.rglob(FILE):
        path.unlink()
    assert tables_main(["release", str(old), "--out", str(tmp_path / "y")]) == 2
    assert "kept its predictions" in capsys.readouterr().err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


@pytest.mark.slow
def test_a_release_with_the_data_moved_names_the_recorded_folder_and_reads_data_dir(
        trained, tmp_path, capsys):
    """The runs' recorded data folder gone, a release is one line naming it and --data-dir (no
    longer the data loader's 'JIGSAWS Suturing folder not found'); given the folder, it writes
    the same files as with the data in place."""
    grid, archive, data = trained
    assert tables_main(["release", str(archive), "--out", str(tmp_path / "here"),
                        "--configs", "A-fixed"]) == 0
    moved = data.parent.parent / "moved"
    data.parent.rename(moved)
    try:
        capsys.readouterr()
        assert tables_main(["release", str(archive), "--out", str(tmp_path / "x"),
                            "--configs", "A-fixed"]) == 2
        error = capsys.readouterr().err.strip()
        assert len(error.splitlines()) == 1 and str(data) in error and "--data-dir" in error
        assert not (tmp_path / "x").exists()
        assert tables_main(["release", str(archive), "--out", str(tmp_path / "elsewhere"),
                            "--configs", "A-fixed", "--data-dir", str(moved / "Suturing")]) == 0
    finally:
        moved.rename(data.parent)
    here, elsewhere = _files(tmp_path / "here"), _files(tmp_path / "elsewhere")
    assert elsewhere == here and len(here) > 1


@pytest.mark.slow
def test_a_release_and_score_say_that_a_release_scores_the_last_evaluation_point(
        trained, tmp_path, capsys):
    """The release's README says that a release scores its runs' last evaluation point, not the
    mean over their points that the archive tabulates, and ``score`` knows a released folder
    (to note it); an unknown configuration is named with those the grid holds."""
    from multitask.evidence.commands.score import release_note, released_from
    from multitask.evidence.studies.release import LAST_POINT

    grid, archive, data = trained
    out = tmp_path / "release"
    assert tables_main(["release", str(archive), "--out", str(out), "--configs", "A-fixed"]) == 0
    assert LAST_POINT.format(frame_hz=30, format="") in (out / "README.md").read_text()
    seed = out / "revised" / "bidirectional" / "A-fixed" / "seed0"
    release = released_from(seed)
    assert (release["grid"], release["sample_hz"]) == (str(archive), [5.0])
    assert released_from(shutil.copytree(seed, tmp_path / "mine" / "seed0")) is None
    assert released_from(out) is None
    assert "scored at its runs' last evaluation point" in release_note(seed, release, 5.0,
                                                                       "revised")
    at_3 = release_note(seed, release | {"sample_hz": [3.0]}, 5.0, "original")
    assert "whose runs predicted at 3 Hz: scored here at 5 Hz samples" in at_3
    assert at_3.endswith("trained on revised labels, scored on original labels (--annotations)")
    record = json.loads((out / "release.json").read_text())
    (out / "release.json").write_text(json.dumps(record | {"sample_hz": "3"}))
    assert released_from(seed)["sample_hz"] is None
    capsys.readouterr()
    assert tables_main(["release", str(archive), "--out", str(tmp_path / "x"),
                        "--configs", "Z-fixed"]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "Z-fixed" in error and "revised/A-fixed" in error


def test_a_release_of_runs_at_another_rate_says_that_score_does_not_give_their_scores():
    """A 3 Hz ED-TCN's release: its README names its rate and that ``score`` (5 Hz samples) does
    not give its runs' scores; at 5 Hz it says what scoring gives (``LAST_POINT``)."""
    from multitask.evidence.studies.release import LAST_POINT, release_readme

    folders = [Path("original/bidirectional/A-fixed/seed0")]
    at_3 = release_readme(Path("results/tcn/retest/ed-tcn-3hz"), folders, [(30.0, 10, "jigsaws")])
    assert "every 10th frame of a trial's labelled span (3 Hz)" in at_3
    assert LAST_POINT.format(frame_hz=30, format="") not in at_3
    assert "scores at 5 Hz samples" in at_3
    assert "does not give its runs' scores" in " ".join(at_3.split())
    at_5 = release_readme(Path("results/reference/grid"), folders, [(30.0, 6, "jigsaws")])
    assert "every 6th frame of a trial's labelled span (5 Hz)" in at_5
    assert LAST_POINT.format(frame_hz=30, format="") in at_5
    assert "# Per-split test predictions of reference/grid" in at_5


def test_a_release_of_recordings_at_another_rate_names_their_rate_frames_and_format():
    """Runs trained on 100 Hz recordings of a user's format (5 Hz models, one sample in 20
    frames): the README names the 100 Hz frames, every 20th frame, ``--rate 100`` and
    ``--format``, and what scoring at 5 Hz gives, not the release's 30 Hz and every 6th frame."""
    from multitask.evidence.studies.release import release_readme

    folders = [Path("revised/bidirectional/A-fixed/seed0")]
    text = release_readme(Path("runs/mine"), folders, [(100.0, 20, "my_robot")])
    flat = " ".join(text.split())
    assert "1-based frame of the 100 Hz recording" in flat
    assert "every 20th frame of a trial's labelled span (5 Hz)" in flat
    assert "`multitask-tables score FOLDER --rate 100` with `--format` naming the my_robot" in flat
    assert "exactly its runs' scores at their last evaluation point" in flat
    assert "30 Hz" not in flat and "6th" not in flat


@pytest.mark.parametrize("recorded", ["3", 3.0, [], [True], [float("inf")], [0], [5.0, None]])
def test_a_release_whose_rate_is_unreadable_is_noted_as_such_not_as_5_hz(tmp_path, recorded):
    """A release.json whose ``sample_hz`` is no list of positive rates: score's note says its
    rate is unknown (a bool read as 1 Hz, a scalar or an empty list as a 5 Hz release);
    without ``sample_hz`` (an older release) its runs are at 5 Hz."""
    from multitask.evidence.commands.score import release_note, released_from

    seed = tmp_path / "rel" / "revised" / "bidirectional" / "A-fixed" / "seed0"
    seed.mkdir(parents=True)
    manifest = tmp_path / "rel" / "release.json"
    manifest.write_text(json.dumps({"grid": "g", "sample_hz": recorded}))
    note = release_note(seed, released_from(seed), 5.0, "revised")
    assert "records no readable rate (sample_hz)" in note and "last evaluation point" not in note
    manifest.write_text(json.dumps({"grid": "g"}))
    assert "last evaluation point" in release_note(seed, released_from(seed), 5.0, "revised")


@pytest.mark.slow
def test_a_release_names_each_run_it_leaves_out(trained, tmp_path, capsys):
    """A run of other settings than its grid's spec, or without kept predictions, is left out
    of a release with a note naming it, not silently."""
    grid, archive, data = trained
    copy = shutil.copytree(archive, tmp_path / "archive")
    other, bare = _runs(copy)[:2]
    config = json.loads((other / "config.json").read_text())
    config["run"]["train"]["batch_size"] += 1
    (other / "config.json").write_text(json.dumps(config))
    for path in bare.rglob(FILE):
        path.unlink()
    capsys.readouterr()
    assert tables_main(["release", str(copy), "--out", str(tmp_path / "out")]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note:")]
    assert any(str(other) in line for line in notes), notes
    assert any(str(bare) in line and "kept no predictions" in line for line in notes), notes


def test_a_release_of_a_grid_whose_every_configuration_still_trains_says_so(trained, tmp_path,
                                                                             capsys):
    """Finished runs exist, but no configuration has all of its: the error says that, not
    "no finished runs", and names each configuration's count."""
    _, archive, _ = trained
    copy = shutil.copytree(archive, tmp_path / "archive")
    for config in sorted(copy.glob("runs/*/*/*")):
        next(iter(sorted(config.rglob("finished.json")))).unlink()
    capsys.readouterr()
    assert tables_main(["release", str(copy), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "no configuration has finished all its runs" in err and "no finished runs" not in err
    counts = re.findall(r"left out: \S+, \d+ of \d+ runs finished", err)
    assert len(counts) == len(list(copy.glob("runs/*/*/*"))) and "Traceback" not in err
    assert not (tmp_path / "out").exists()
    one = shutil.copytree(archive, tmp_path / "one")         # one configuration unfinished
    config = sorted(one.glob("runs/*/*/*"))[0]
    next(iter(sorted(config.rglob("finished.json")))).unlink()
    name = f"{config.parts[-3]}/{config.name}"
    assert tables_main(["release", str(one), "--configs", name, "--out",
                        str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert re.search(rf"configuration {name} has not finished all its runs \(\S+, \d+ of \d+ "
                     r"runs finished\)", err), err
    assert "no finished run" not in err and not (tmp_path / "out").exists()
