"""``multitask.train`` (the Python training API) and ``--mlflow`` (runs logged to MLflow): the
API trains as the command does and returns the loaded run; a misspelt setting is named with the
nearest; a finished run reaches an MLflow file store with its settings, one metric per
history.csv row and column, and its final scores, once however often the command runs; a grid is
one parent run with its runs nested under it."""
from __future__ import annotations

import errno
import importlib.util
import json
import os
import socket
from pathlib import Path

import pandas as pd
import pytest

import multitask
from jigsaws_tools.errors import WriteFailed
from multitask.train_cli import main as train_main
from test_archive_and_inputs import at_most

TINY = {"hidden": 8, "epochs": 1, "test_user": "C", "no_plots": True}

needs_mlflow = pytest.mark.skipif(importlib.util.find_spec("mlflow") is None,
                                  reason="MLflow is not installed (pip install -e '.[mlflow]')")


def test_train_returns_the_loaded_run_as_the_command_trains_it(synth_dir, tmp_path):
    lines = []
    run = multitask.train(variant="APoc", weighting="gradnorm", data_dir=synth_dir,
                          out=tmp_path / "api", log=lines.append, **TINY)
    assert (run.variant, run.run_dir, run.config.encoder.hidden) == ("APoc", tmp_path / "api", 8)
    assert lines[0].startswith("model: APoc (gestures + progress by ordered classification), "
                               "GradNorm task weights")
    assert [t.name for t in run.tasks] == ["gesture", "progress"]
    assert train_main(["--variant", "APoc", "--weighting", "gradnorm", "--data-dir",
                       str(synth_dir), "--out", str(tmp_path / "cli"), "--hidden", "8",
                       "--epochs", "1", "--test-user", "C", "--no-plots"]) == 0
    for name in ("history.csv", "gradnorm.csv"):       # the same run, loss for loss
        api, cli = (pd.read_csv(tmp_path / side / name) for side in ("api", "cli"))
        pd.testing.assert_frame_equal(api.filter(like="loss"), cli.filter(like="loss"))
    again = multitask.train(variant="APoc", weighting="gradnorm", data_dir=synth_dir,
                            out=tmp_path / "api", log=lines.append, **TINY)
    assert again.checkpoint == run.checkpoint and run.finished and "already finished" in lines[-1]


@pytest.mark.parametrize("settings,message", [
    ({"hiden": 8}, "no setting 'hiden'; did you mean 'hidden'?"),
    ({"hidden": 0}, "argument --hidden"),
    ({"variant": "APx"}, "argument --variant: invalid choice: 'APx'"),
    ({"variant": "A", "weighting": "gradnorm"}, "GradNorm needs two tasks"),
    ({"alpha": 2.0}, "--alpha is a GradNorm setting"),
    ({"monitor_train": "yes"}, "monitor_train: True or False"),
    ({"help": True}, "no setting 'help'"),
])
def test_a_bad_setting_is_a_value_error_before_any_work(settings, message, tmp_path):
    with pytest.raises(ValueError, match=message.replace("?", r"\?")):
        multitask.train(out=tmp_path / "run", synthetic=True, log=None, **settings)
    assert not (tmp_path / "run").exists()


@needs_mlflow
@pytest.mark.slow
def test_a_finished_run_is_logged_to_mlflow_once(synth_dir, tmp_path, monkeypatch, capsys):
    """To a folder (MLflow's file store, without ``MLFLOW_ALLOW_FILE_STORE``), from a run
    folder whose path holds the characters a search filter quotes (issue 66: such a run was
    logged again by each call): once, whole, its record and figures as artifacts."""
    from mlflow.tracking import MlflowClient

    monkeypatch.delenv("MLFLOW_ALLOW_FILE_STORE", raising=False)
    uri = (tmp_path / "mlruns").as_uri()
    out = tmp_path / "it's a \\ run_%"
    command = ["--variant", "APc", "--weighting", "gradnorm", "--data-dir", str(synth_dir),
               "--out", str(out),
               "--hidden", "8", "--epochs", "2", "--eval-at", "1,2", "--test-user", "C",
               "--mlflow", uri]
    assert train_main(command) == 0
    assert f"logged to {uri}" in capsys.readouterr().out
    assert train_main(command) == 0                                # finished: not logged twice
    assert "MLFLOW_ALLOW_FILE_STORE" not in os.environ
    client = MlflowClient(tracking_uri=uri)
    experiment = client.get_experiment_by_name("mtrnn-jigsaws")
    runs = client.search_runs([experiment.experiment_id])
    assert len(runs) == 1
    run = runs[0]
    assert run.data.params["variant"] == "APc" and run.data.params["run.encoder.hidden"] == "8"
    assert run.data.params["run.test_user"] == "C"
    artifacts = {a.path for a in client.list_artifacts(run.info.run_id)}
    assert {"config.json", "metrics.json", "history.csv", "gradnorm.csv", "eval"} <= artifacts
    point = {a.path for a in client.list_artifacts(run.info.run_id, "eval/epoch0002")}
    assert point == {"eval/epoch0002/metrics.json", "eval/epoch0002/plots"}
    assert {a.path for a in client.list_artifacts(run.info.run_id, "eval/epoch0002/plots")} == {
        f"eval/epoch0002/plots/{p.name}" for p in (out / "eval/epoch0002/plots").iterdir()}
    recorded = json.loads((out / "config.json").read_text())
    assert run.data.params["run.encoder.loops"] == "auto"                  # what was asked
    assert run.data.tags["mtrnn.loops"] == recorded["provenance"]["loops"] != "auto"   # what ran
    history = pd.read_csv(out / "history.csv")
    losses = client.get_metric_history(run.info.run_id, "loss_gesture")
    assert [m.step for m in losses] == list(history.sweep)
    assert [m.value for m in losses] == pytest.approx(list(history.loss_gesture))
    assert [m.value for m in client.get_metric_history(run.info.run_id, "epoch")] == [1, 2]
    weights = pd.read_csv(out / "gradnorm.csv")
    assert [m.value for m in client.get_metric_history(
        run.info.run_id, "gradnorm.w_end_progress")] == pytest.approx(list(weights.w_end_progress))
    metrics = pd.read_json(out / "metrics.json", typ="series")["mean"]
    assert run.data.metrics["final.gesture.accuracy"] == pytest.approx(
        metrics["gesture"]["accuracy"])
    assert run.data.metrics["final.gesture.f1_10"] == pytest.approx(metrics["gesture"]["f1@10"])


@pytest.mark.parametrize("uri", ["bogus://nowhere", "http://127.0.0.1:{port}",
                                 "sqlite:///{tmp}/a-folder", "sqlite:///{tmp}/notes.txt",
                                 "sqlite:///{tmp}/notes.txt/mlflow.db",
                                 "sqlite:///{tmp}/no-folder/mlflow.db",
                                 "sqlite:////proc/mtrnn-mlflow.db"])
def test_an_unusable_tracking_uri_stops_before_any_work(tmp_path, capsys, uri):
    """An unknown scheme, a server that does not answer (issue 66: about 4 minutes of retries)
    or a database file that is none or cannot be created (a missing folder, ``/proc``: MLflow
    retries it for two minutes, 36 lines of warnings) is one line before any work, within
    seconds."""
    (tmp_path / "a-folder").mkdir()
    (tmp_path / "notes.txt").write_text("mine")
    with socket.socket() as closed:                         # a port nothing listens on
        closed.bind(("127.0.0.1", 0))
        uri = uri.format(port=closed.getsockname()[1], tmp=tmp_path)
    with at_most(120):
        code = train_main(["--synthetic", "--out", str(tmp_path / "run"), "--mlflow", uri])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "multitask-train: error:" in err
    assert ("--mlflow" in err or "MLflow is not installed" in err)
    if "http" in uri and importlib.util.find_spec("mlflow") is not None:
        assert "no MLflow tracking server answers there" in err
    if uri.startswith("bogus") and importlib.util.find_spec("mlflow") is not None:
        assert "unsupported scheme 'bogus'" in err and "sqlite:" in err
    assert not (tmp_path / "run").exists() and (tmp_path / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-folder", "notes.txt"]


def _finished_run(folder: Path) -> Path:
    """A finished run folder as the tracker reads it, without training one."""
    folder.mkdir(parents=True)
    (folder / "config.json").write_text(json.dumps({
        "variant": "A", "weighting": "fixed", "settings_hash": "0123abcd",
        "run": {"test_user": "B"}}))
    (folder / "metrics.json").write_text(json.dumps({"mean": {"gesture": {"accuracy": 50.0}}}))
    (folder / "history.csv").write_text("unit,n,sweep,lr,loss_gesture,elapsed_seconds\n"
                                        "epochs,1,7,1.0,0.5,2.0\n")
    (folder / "finished.json").write_text("{}")
    return folder


@needs_mlflow
def test_the_documented_sqlite_store_works_and_a_cut_logging_is_redone(tmp_path, monkeypatch):
    """``sqlite:///mlflow.db`` as the README says, with the ``[mlflow]`` extra; a run whose
    logging was cut short (created, never marked finished) is logged again whole in its place;
    runs whose paths differ only in characters a filter quotes are told apart."""
    from rnn_seg.runs.tracking import Tracker

    monkeypatch.chdir(tmp_path)
    tracker = Tracker("sqlite:///mlflow.db")
    runs = [_finished_run(tmp_path / name) for name in ("it's", "it_s", "a\\b", "a%b")]
    cut = tracker.client.create_run(tracker.experiment, tags={
        "mtrnn.run_dir": str(runs[0].resolve()), "mtrnn.settings_hash": "0123abcd"})
    ids = [tracker.log_run(run) for run in runs]
    assert len(set(ids)) == 4 and cut.info.run_id not in ids
    assert [tracker.log_run(run) for run in runs] == ids
    active = tracker.client.search_runs([tracker.experiment])
    assert sorted(r.info.run_id for r in active) == sorted(ids)
    assert {r.info.status for r in active} == {"FINISHED"}
    assert {a.path for a in tracker.client.list_artifacts(ids[0])} == {
        "config.json", "metrics.json", "history.csv", "finished.json"}


@pytest.mark.parametrize("settings, raised", [
    ({"data_dir": "/nonexistent/Suturing"}, FileNotFoundError),
    ({"synthetic": True, "out": ""}, ValueError),
    ({"synthetic": True, "mlflow": " "}, ValueError),
    ({"synthetic": True, "task_file": "missing.toml"}, ValueError),
    ({"synthetic": True, "full_disk": True}, WriteFailed),
])
def test_train_raises_what_its_docstring_says(tmp_path, monkeypatch, settings, raised):
    """Each error of ``multitask.train`` is of the class its docstring names for it: a missing
    release a ``FileNotFoundError``, a bad value a ``ValueError``, a full disk ``WriteFailed``
    (naming the file, as the command does) rather than the system's ``OSError``."""
    settings = {"out": tmp_path / "run", "log": None, **TINY, **settings}
    if settings.pop("full_disk", False):
        def full(*args, **kwargs):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "run" / "x"))
        monkeypatch.setattr("multitask.training.train_configured", full)
    with pytest.raises(raised) as error:
        multitask.train(**settings)
    assert "\n" not in str(error.value).split("JIGSAWS is distributed")[0].strip()
    assert raised is not WriteFailed or f"cannot write {tmp_path / 'run' / 'x'}" in str(
        error.value)


@needs_mlflow
@pytest.mark.slow
def test_a_grid_is_a_parent_run_with_its_runs_nested_under_it(synth_dir, tmp_path,
                                                               monkeypatch):
    from mlflow.tracking import MlflowClient

    from multitask.grid.cli import main as grid_main

    monkeypatch.setenv("MLFLOW_EXPERIMENT_NAME", "grids")
    spec = tmp_path / "spec.toml"
    spec.write_text(f'preset = "quick"\ndata_dir = "{synth_dir}"\ntest_users = ["B"]\n'
                    'hidden = 8\nepochs = 2\n[[experiments]]\nvariants = ["A"]\n')
    uri = (tmp_path / "mlruns").as_uri()
    command = ["--spec", str(spec), "--out", str(tmp_path / "grid"), "--workers", "0"]
    assert grid_main(command) == 0                          # trained without MLflow first
    assert grid_main(command + ["--mlflow", uri]) == 0      # its finished runs logged now
    client = MlflowClient(tracking_uri=uri)
    runs = client.search_runs([client.get_experiment_by_name("grids").experiment_id])
    parents = [r for r in runs if "mtrnn.grid_dir" in r.data.tags]
    assert len(parents) == 1 and parents[0].info.status == "FINISHED"
    assert parents[0].data.params["hidden"] == "8"
    children = [r for r in runs if r.data.tags.get("mlflow.parentRunId")
                == parents[0].info.run_id]
    assert [r.data.params["variant"] for r in children] == ["A"]
    assert len(runs) == 2 and all("final.gesture.accuracy" in r.data.metrics for r in children)
