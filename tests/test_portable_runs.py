"""Run folders that work from any working directory (issue #48): a run records its data folder
absolute and as typed; every command that reads a run finds it from anywhere; a recorded folder
that is gone is one line naming it as the run's recorded path and the override, --data-dir."""
from __future__ import annotations

import json
import shutil

import pytest

from multitask.inference.evaluate_cli import main as evaluate_main
from multitask.inference.predict_cli import main as predict_main
from multitask.train_cli import main as train_main


@pytest.fixture(scope="module")
def trained_here(synth_dir, tmp_path_factory):
    """A forward run trained in one folder, with --data-dir and --out relative to it."""
    base = tmp_path_factory.mktemp("portable")
    shutil.copytree(synth_dir, base / "data" / "Suturing")
    (base / "lab").mkdir()
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(base / "lab")
        assert train_main(["--data-dir", "../data/Suturing", "--variant", "A", "--hidden", "8",
                           "--epochs", "1", "--direction", "forward", "--no-plots",
                           "--threads", "1", "--out", "runs/fw"]) == 0
    return base


def _config(run_dir):
    return json.loads((run_dir / "config.json").read_text())


def test_a_run_records_its_data_folder_absolute_and_as_typed(trained_here):
    data = _config(trained_here / "lab" / "runs" / "fw")["run"]["data"]
    assert data["data_dir"] == str((trained_here / "data" / "Suturing").resolve())
    assert data["data_dir_as_given"] == "../data/Suturing"


def test_a_run_trained_in_one_folder_is_evaluated_and_streamed_from_another(
        trained_here, tmp_path, monkeypatch, capsys):
    run_dir = trained_here / "lab" / "runs" / "fw"
    monkeypatch.chdir(tmp_path)                       # no ../data/Suturing from here
    assert evaluate_main([str(run_dir), "--out", "scores", "--no-plots"]) == 0
    assert json.loads((tmp_path / "scores" / "metrics.json").read_text())["metrics"]
    recording = trained_here / "data" / "Suturing" / "kinematics" / "AllGestures"
    assert predict_main([str(run_dir), str(recording / "Suturing_B001.txt"), "--stream",
                         "--no-plots", "--out", "labels"]) == 0
    assert (tmp_path / "labels" / "Suturing_B001.csv").is_file()
    assert "error" not in capsys.readouterr().err


def _as_an_earlier_version_wrote_it(run_dir, data_dir: str) -> None:
    """config.json of a run of an earlier version: the data folder as typed, no
    data_dir_as_given; no saved stream statistics."""
    saved = _config(run_dir)
    saved["run"]["data"].pop("data_dir_as_given", None)
    saved["run"]["data"]["data_dir"] = data_dir
    (run_dir / "config.json").write_text(json.dumps(saved))
    (run_dir / "stream_normalisation.json").unlink(missing_ok=True)


def test_an_earlier_runs_relative_folder_is_read_from_the_working_directory(
        trained_here, tmp_path, monkeypatch, capsys):
    run_dir = tmp_path / "old_run"
    shutil.copytree(trained_here / "lab" / "runs" / "fw", run_dir)
    _as_an_earlier_version_wrote_it(run_dir, "../data/Suturing")
    monkeypatch.chdir(trained_here / "lab")           # where it was trained: found
    assert evaluate_main([str(run_dir), "--out", str(tmp_path / "here"), "--no-plots"]) == 0
    monkeypatch.chdir(tmp_path)                       # elsewhere: one line, and the override
    for main, argv in ((evaluate_main, ["--out", "there"]),
                       (predict_main, [str(trained_here / "data" / "Suturing" / "kinematics" /
                                           "AllGestures" / "Suturing_B001.txt"),
                                       "--stream", "--out", "labels"])):
        assert main([str(run_dir), *argv, "--no-plots"]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err
        assert ("../data/Suturing: no such folder; it is the data folder run "
                f"{run_dir} recorded" in err), err
        assert f"relative to the working directory {tmp_path}" in err and "--data-dir" in err
        assert "registration" not in err                # not the how-to-obtain-JIGSAWS blurb
    assert not (tmp_path / "there").exists() and not (tmp_path / "labels").exists()
    assert evaluate_main([str(run_dir), "--data-dir", str(trained_here / "data" / "Suturing"),
                          "--out", "there", "--no-plots"]) == 0


def test_a_moved_data_folder_names_the_recorded_path_and_how_it_was_typed(
        trained_here, tmp_path, capsys):
    run_dir = tmp_path / "run"
    shutil.copytree(trained_here / "lab" / "runs" / "fw", run_dir)
    saved = _config(run_dir)
    gone = tmp_path / "moved" / "Suturing"
    saved["run"]["data"]["data_dir"] = str(gone)
    (run_dir / "config.json").write_text(json.dumps(saved))
    assert evaluate_main([str(run_dir), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert f"{gone}: no such folder; it is the data folder run {run_dir} recorded" in err
    assert "typed as ../data/Suturing" in err and "--data-dir DIR" in err
    assert not (run_dir / "evaluate").exists()
