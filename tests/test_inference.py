"""Using a trained run: predict new recordings, evaluate saved weights, stream, export, the API."""
import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import tensorflow as tf

import multitask
from baseline.builder import train_baseline
from baseline.config import RunConfig
from jigsaws_tools.dataset import DataConfig, load_dataset
from jigsaws_tools.gestures import GESTURES
from jigsaws_tools.release import frame_labels, kinematics_dir, read_kinematics, read_transcription
from jigsaws_tools.release import transcriptions_dir
from jigsaws_tools.task_definition import SUTURING
from multitask.inference.evaluate_cli import main as evaluate_main
from multitask.inference.export_cli import main as export_main
from multitask.models.fold_run import train_variant
from multitask.inference.predict_cli import kinematics_files
from multitask.inference.predict_cli import main as predict_main
from multitask.inference.streaming import StreamingPredictor, stream_recording
from multitask.inference.trained_run import STREAM_NORMALISATION_FILE, load_run
from rnn_seg.runs.checkpoints import checkpoint_sweeps
from multitask.models.variants import get_variant
from rnn_seg.lstm import EncoderConfig
from rnn_seg.optim import OptimConfig
from rnn_seg.trainer import TrainConfig

EPOCHS = 3


def _config(synth_dir, bidirectional):
    return RunConfig(data=DataConfig(str(synth_dir)), test_user="B",
                     encoder=EncoderConfig(hidden=16, bidirectional=bidirectional),
                     optim=OptimConfig(total=EPOCHS, decay_start=2),
                     train=TrainConfig(eval_points=(EPOCHS,), plots="none"))


@pytest.fixture(scope="module")
def bi_run(synth_dir, tmp_path_factory):
    """APoc (gestures + ordinal progress), bidirectional, trained by multitask's fold runner."""
    config = _config(synth_dir, bidirectional=True)
    run_dir = tmp_path_factory.mktemp("bi") / "run"
    train_variant(get_variant("APoc"), "fixed", config, run_dir,
                  dataset=load_dataset(config.data, use_cache=False), log=lambda m: None)
    return run_dir


@pytest.fixture(scope="module")
def fw_run(synth_dir, tmp_path_factory):
    """Model A's forward (online) twin, trained by baseline-train's code (no variant recorded)."""
    config = _config(synth_dir, bidirectional=False)
    run_dir = tmp_path_factory.mktemp("fw") / "run"
    train_baseline(config, run_dir, dataset=load_dataset(config.data, use_cache=False),
                   log=lambda m: None)
    return run_dir


def _last_point(run_dir):
    return run_dir / "eval" / f"epoch{EPOCHS:04d}"


def _held_out(synth_dir, name="Suturing_B002"):
    """A held-out trial's kinematics file and its per-frame gesture labels (-1 = unlabelled)."""
    path = kinematics_dir(synth_dir) / f"{name}.txt"
    n = len(read_kinematics(path))
    return path, frame_labels(read_transcription(transcriptions_dir(synth_dir) / f"{name}.txt"), n)


# -- multitask-predict -----------------------------------------------------------------------------
def test_predict_labels_every_frame_of_a_recording_without_transcription(bi_run, synth_dir,
                                                                         tmp_path, capsys):
    kinematics, truth = _held_out(synth_dir)
    inputs = tmp_path / "recordings"
    inputs.mkdir()
    shutil.copy(kinematics, inputs / "mine.txt")                 # no transcription anywhere
    assert predict_main([str(bi_run), str(inputs), "--out", str(tmp_path / "out")]) == 0
    assert "done: 1 recording(s)" in capsys.readouterr().out
    table = pd.read_csv(tmp_path / "out" / "mine.csv")
    assert list(table["frame"]) == list(range(1, len(truth) + 1))
    assert set(table["gesture"]) <= set(GESTURES)
    np.testing.assert_allclose(table.filter(like="gesture_p_").sum(axis=1), 1.0, atol=1e-4)
    assert list(table.columns[:3]) == ["frame", "time_s", "sample"]
    np.testing.assert_allclose(table["time_s"], (table["frame"] - 1) / 30, atol=1e-5)
    assert set(table["progress"]) <= set(SUTURING.stage_names) and "progress_y_drop" in table
    assert (tmp_path / "out" / "mine.png").is_file()
    record = json.loads((tmp_path / "out" / "prediction.json").read_text())
    assert record["recordings"]["mine"]["frames"] == len(truth) and record["mode"] == "offline"
    # the frames' labels line up with the recording: well above chance on this held-out trial
    labelled = truth >= 0
    predicted = np.array([GESTURES.index(g) for g in table["gesture"]])
    accuracy = 100 * np.mean(predicted[labelled] == truth[labelled])
    majority = 100 * np.bincount(truth[labelled]).max() / labelled.sum()
    assert accuracy > majority + 15, (accuracy, majority)


def test_predict_refuses_to_overwrite_and_reports_bad_input(bi_run, synth_dir, tmp_path, capsys):
    kinematics, _ = _held_out(synth_dir)
    out = tmp_path / "out"
    assert predict_main([str(bi_run), str(kinematics), "--out", str(out), "--no-plots"]) == 0
    assert predict_main([str(bi_run), str(kinematics), "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err
    assert predict_main([str(bi_run), str(kinematics), "--out", str(out), "--overwrite",
                         "--no-plots"]) == 0
    bad = tmp_path / "bad.txt"
    lines = kinematics.read_text().splitlines()
    lines[41] = lines[41].replace(lines[41].split()[5], "x1.5", 1)
    bad.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert predict_main([str(bi_run), str(bad), "--out", str(tmp_path / "o2")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("multitask-predict: error: ") and f"{bad}:42" in err and "x1.5" in err
    assert "Traceback" not in err and not (tmp_path / "o2" / "prediction.json").exists()
    for argv, words in (([str(tmp_path / "nothing.txt")], "no such file or folder"),
                        ([str(kinematics), "--checkpoint", "5"], "no checkpoint after sweep 5"),
                        ([str(kinematics), "--stream"], "forward (online) model")):
        assert predict_main([str(bi_run), *argv, "--out", str(tmp_path / "o3")]) == 2
        assert words in capsys.readouterr().err


def test_predict_overwrite_replaces_the_earlier_prediction_whole(bi_run, synth_dir, tmp_path,
                                                                  capsys):
    """The folder never holds outputs its record does not list: --overwrite removes the earlier
    prediction's files (and only those), an existing file as --out is one line."""
    first, _ = _held_out(synth_dir, "Suturing_B002")
    second, _ = _held_out(synth_dir, "Suturing_B003")
    out = tmp_path / "out"
    assert predict_main([str(bi_run), str(first), "--out", str(out), "--no-plots"]) == 0
    (out / "notes.txt").write_text("mine")
    (out / "Suturing_B002.png").write_text("mine too: the prediction drew no plot")
    assert predict_main([str(bi_run), str(second), "--out", str(out), "--no-plots"]) == 2
    assert "use --overwrite" in capsys.readouterr().err
    assert predict_main([str(bi_run), str(second), "--out", str(out), "--no-plots",
                         "--overwrite"]) == 0
    record = json.loads((out / "prediction.json").read_text())
    assert list(record["recordings"]) == ["Suturing_B003"]
    assert sorted(p.name for p in out.iterdir()) == ["Suturing_B002.png", "Suturing_B003.csv",
                                                     "notes.txt", "prediction.json"]
    assert record["files"] == ["Suturing_B003.csv"]
    capsys.readouterr()
    assert predict_main([str(bi_run), str(first), "--out", str(out / "notes.txt")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "notes.txt is a file, not a folder" in err, err
    assert (out / "notes.txt").read_text() == "mine"


def test_predict_never_writes_over_an_input_recording(bi_run, synth_dir, tmp_path, capsys):
    """An input named like an output (NAME.csv) in --out is refused even with --overwrite."""
    kinematics, _ = _held_out(synth_dir)
    folder = tmp_path / "mine"
    folder.mkdir()
    recording = folder / "session.csv"
    shutil.copy(kinematics, recording)
    for extra in ([], ["--overwrite"]):
        assert predict_main([str(bi_run), str(recording), "--out", str(folder), *extra]) == 2
        assert "is an input recording" in capsys.readouterr().err
    assert recording.read_bytes() == kinematics.read_bytes()
    assert sorted(p.name for p in folder.iterdir()) == ["session.csv"]


def test_a_config_json_that_does_not_fit_is_a_clear_error(bi_run, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(bi_run, run)
    config = json.loads((run / "config.json").read_text())
    config["run"]["encoder"]["hiden"] = 16
    (run / "config.json").write_text(json.dumps(config))
    assert evaluate_main([str(run)]) == 2
    assert "config.json: run.encoder: unknown field 'hiden'" in capsys.readouterr().err
    del config["run"]["encoder"]["hiden"], config["variant"]
    (run / "config.json").write_text(json.dumps(config))
    assert evaluate_main([str(run)]) == 2
    assert "are not variant A's" in capsys.readouterr().err


# -- multitask-evaluate ----------------------------------------------------------------------------
def test_evaluate_reproduces_the_runs_last_evaluation_exactly(bi_run, tmp_path):
    out = tmp_path / "evaluation"
    assert evaluate_main([str(bi_run), "--out", str(out), "--no-plots"]) == 0
    saved = json.loads((_last_point(bi_run) / "metrics.json").read_text())
    again = json.loads((out / "metrics.json").read_text())
    assert again["metrics"] == saved["metrics"] and again["confusion"] == saved["confusion"]
    assert (again["point"], again["unit"]) == (saved["point"], saved["unit"])
    for csv in sorted((_last_point(bi_run) / "predictions").glob("*.csv")):
        assert (out / "predictions" / csv.name).read_text() == csv.read_text()


def test_evaluate_refuses_other_data_in_the_runs_folder_and_marks_other_data_named(
        bi_run, synth_dir, tmp_path, capsys, caplog):
    """Data in the run's recorded folder that is not what it trained on (moved, changed, or a
    relative folder read from elsewhere) never passes for its held-out scores."""
    run = tmp_path / "run"
    shutil.copytree(bi_run, run)
    config = json.loads((run / "config.json").read_text())
    config["data_fingerprint"] = "0" * 24                  # as if the release had changed since
    (run / "config.json").write_text(json.dumps(config))
    assert evaluate_main([str(run), "--out", str(tmp_path / "e1"), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "is not the data" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "e1").exists()
    assert evaluate_main([str(run), "--out", str(tmp_path / "e2"), "--no-plots",
                          "--data-dir", str(synth_dir)]) == 0
    assert "not the run's held-out scores" in caplog.text
    marked = json.loads((tmp_path / "e2" / "metrics.json").read_text())
    assert marked["trained_on_this_data"] is False
    assert evaluate_main([str(bi_run), "--out", str(tmp_path / "e3"), "--no-plots"]) == 0
    assert json.loads((tmp_path / "e3" / "metrics.json").read_text())["trained_on_this_data"]


def test_a_run_without_a_recorded_fingerprint_is_evaluated_unchecked(bi_run, tmp_path, caplog):
    """Runs of early versions recorded no data fingerprint: scored as before, with a warning."""
    run = tmp_path / "run"
    shutil.copytree(bi_run, run)
    config = json.loads((run / "config.json").read_text())
    del config["data_fingerprint"]
    (run / "config.json").write_text(json.dumps(config))
    assert evaluate_main([str(run), "--out", str(tmp_path / "e"), "--no-plots"]) == 0
    assert "records no data fingerprint" in caplog.text
    metrics = json.loads((tmp_path / "e" / "metrics.json").read_text())
    assert metrics["trained_on_this_data"] is None
    assert metrics["metrics"] == json.loads((_last_point(bi_run) / "metrics.json").read_text())[
        "metrics"]


def test_evaluate_and_export_refuse_a_non_empty_folder_before_any_work(bi_run, tmp_path, capsys,
                                                                       monkeypatch):
    import multitask.inference.evaluation as evaluation
    import multitask.inference.export as export

    def no_work(*args, **kwargs):
        raise AssertionError("work started before the output folder was checked")

    monkeypatch.setattr(evaluation, "load_dataset", no_work)
    monkeypatch.setattr(export, "ExportedRun", no_work)
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    link, empty = tmp_path / "link", tmp_path / "empty"
    empty.mkdir()
    link.symlink_to(empty)
    for main in (evaluate_main, export_main):
        assert main([str(bi_run), "--out", str(out)]) == 2
        assert "exists and is not empty" in capsys.readouterr().err
        for extra in ([], ["--overwrite"]):
            assert main([str(bi_run), "--out", str(link), *extra]) == 2
            assert "is a symbolic link" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["notes.txt"] and link.is_symlink()


def test_every_predictions_csv_has_predicts_columns_and_names(bi_run, synth_dir, tmp_path):
    """One format: multitask-predict's columns (per 30 Hz frame) are all in an evaluation point's
    CSV (per 5 Hz sample, true labels beside), with class names, never indices; the confusion
    matrices count exactly the rows written."""
    kinematics = _held_out(synth_dir)[0]
    assert predict_main([str(bi_run), str(kinematics), "--out", str(tmp_path / "p"),
                         "--no-plots"]) == 0
    predicted = pd.read_csv(tmp_path / "p" / f"{kinematics.stem}.csv")
    evaluation = pd.read_csv(_last_point(bi_run) / "predictions" / f"{kinematics.stem}.csv")
    assert set(predicted.columns) < set(evaluation.columns)
    assert set(evaluation.columns) - set(predicted.columns) == {"gesture_true", "progress_true"}
    stages = SUTURING.stage_names
    for table in (predicted, evaluation):
        assert set(table["gesture"]) <= set(GESTURES) and set(table["progress"]) <= set(stages)
        np.testing.assert_allclose(table["time_s"], (table["frame"] - 1) / 30, atol=1e-5)
    assert set(evaluation["progress_true"]) <= set(stages)
    assert list(evaluation["sample"]) == list(range(len(evaluation)))    # one row per sample
    assert list(predicted["frame"]) == list(range(1, len(predicted) + 1))  # one row per frame
    saved = json.loads((_last_point(bi_run) / "metrics.json").read_text())
    rows = sum(len(pd.read_csv(c)) for c in (_last_point(bi_run) / "predictions").glob("*.csv"))
    for task, names in (("gesture", list(GESTURES)), ("progress", list(stages))):
        assert saved["confusion"][task]["classes"] == names
        assert np.sum(saved["confusion"][task]["counts"]) == rows


# -- streaming -------------------------------------------------------------------------------------
@pytest.mark.slow
def test_streaming_equals_the_whole_sequence_under_causal_preprocessing(fw_run, synth_dir):
    run = load_run(fw_run)
    assert run.variant == "A" and [t.name for t in run.tasks] == ["gesture"]
    kinematics = read_kinematics(_held_out(synth_dir)[0])[:500]
    predictor = StreamingPredictor(run)                 # statistics of the training trials
    assert (fw_run / STREAM_NORMALISATION_FILE).is_file()
    streamed = stream_recording(predictor, kinematics)
    whole = run.predict(kinematics, causal=True, normalisation=predictor.normalisation)
    np.testing.assert_array_equal(streamed.sample_frames, whole.sample_frames)
    np.testing.assert_allclose(streamed.outputs["gesture"], whole.outputs["gesture"],
                               rtol=1e-5, atol=1e-5)
    predictor.reset()
    first = predictor.push(kinematics[0])
    assert first.frame == 1 and first.label_names["gesture"] == GESTURES[first.labels["gesture"]]
    assert all(predictor.push(frame) is None for frame in kinematics[1:6])
    assert predictor.push(kinematics[6]).frame == 7
    for value, problem in ((np.nan, "non-finite"), (-1e39, "kinematic value beyond float32's")):
        broken = kinematics[7].copy()
        broken[3] = value
        with pytest.raises(ValueError, match=rf"frame 8, column 4: {problem}"):
            predictor.push(broken)                      # not taken: the stream goes on
    assert all(predictor.push(frame) is None for frame in kinematics[7:12])
    assert predictor.push(kinematics[12]).frame == 13


def test_labels_are_class_indices_and_label_names_their_names_offline_and_streaming(
        fw_run, synth_dir):
    """One convention: ``labels`` are class indices (as the SavedModel's outputs), ``label_names``
    the classes' names (as every predictions CSV), for a recording and for a streamed sample."""
    run = load_run(fw_run)
    kinematics = read_kinematics(_held_out(synth_dir)[0])[:300]
    offline = run.predict(kinematics)
    indices, names = offline.labels("gesture"), offline.label_names("gesture")
    assert indices.dtype.kind == "i" and len(indices) == len(names) == len(kinematics)
    assert list(names) == [GESTURES[i] for i in indices] == list(offline.table()["gesture"])
    predictor = StreamingPredictor(run)
    samples = [s for s in map(predictor.push, kinematics) if s is not None]
    streamed = stream_recording(predictor, kinematics)
    assert [s.labels["gesture"] for s in samples] == list(streamed.sample_labels("gesture"))
    assert all(isinstance(s.labels["gesture"], int)
               and s.label_names["gesture"] == GESTURES[s.labels["gesture"]] for s in samples)


def test_stream_evaluation_scores_the_offline_samples(fw_run, tmp_path):
    assert evaluate_main([str(fw_run), "--stream", "--out", str(tmp_path / "s"),
                          "--no-plots"]) == 0
    metrics = json.loads((tmp_path / "s" / "metrics.json").read_text())
    assert metrics["preprocessing"] == "stream"
    for csv in sorted((_last_point(fw_run) / "predictions").glob("*.csv")):
        offline, stream = pd.read_csv(csv), pd.read_csv(tmp_path / "s" / "predictions" / csv.name)
        assert stream[["frame", "gesture_true"]].equals(offline[["frame", "gesture_true"]])
    offline = json.loads((_last_point(fw_run) / "metrics.json").read_text())["metrics"]
    assert metrics["metrics"]["gesture"]["accuracy"] > offline["gesture"]["accuracy"] - 25


def test_recordings_of_another_layout_get_the_advice_of_the_mode_that_reads_them(
        fw_run, synth_dir, tmp_path, capsys):
    """Prediction (offline and --stream) and offline evaluation take --format and suggest it;
    evaluate --stream reads the run's layout only and says so, pointing to the offline mode with
    --format."""
    kinematics, _ = _held_out(synth_dir)
    narrow = tmp_path / "narrow.txt"
    narrow.write_text("".join(" ".join(line.split()[:70]) + "\n"
                              for line in kinematics.read_text().splitlines()))
    robot = tmp_path / "robot"
    robot.mkdir()
    (robot / "log.csv").write_text("time,x\n0,1\n")
    commands = {(predict_main, "predict"): [str(narrow)],
                (evaluate_main, "evaluate"): ["--data-dir", str(robot)]}
    for (main, command), argv in commands.items():
        for stream in ([], ["--stream"]):
            assert main([str(fw_run), *argv, *stream, "--out", str(tmp_path / "out"),
                         "--no-plots"]) == 2
            err = capsys.readouterr().err
            assert argv[-1] in err and "Traceback" not in err, err
            only_offline = bool(stream) and command == "evaluate"
            assert ("need --format FILE.toml" in err) == (not only_offline), err
            assert not only_offline or "evaluate offline, without --stream, with --format" in err


def test_stream_normalisation_is_read_back_without_the_data(fw_run, tmp_path):
    run_dir = tmp_path / "run"
    shutil.copytree(fw_run, run_dir)
    run = load_run(run_dir)
    saved = run.stream_normalisation(data_dir=tmp_path / "no-data-here")
    assert saved == load_run(fw_run).stream_normalisation()


def test_stream_statistics_of_other_data_are_used_but_not_saved(fw_run, synth_dir, tmp_path,
                                                                caplog):
    run_dir = tmp_path / "run"
    shutil.copytree(fw_run, run_dir)
    (run_dir / STREAM_NORMALISATION_FILE).unlink(missing_ok=True)
    other = tmp_path / "other"
    shutil.copytree(synth_dir, other)
    changed = kinematics_dir(other) / "Suturing_C001.txt"           # a training trial
    changed.write_text(changed.read_text().replace("1", "2", 40))
    run = load_run(run_dir)
    stats = run.stream_normalisation(data_dir=other)
    assert "not saved" in caplog.text and not (run_dir / STREAM_NORMALISATION_FILE).exists()
    saved = run.stream_normalisation(data_dir=synth_dir)
    assert (run_dir / STREAM_NORMALISATION_FILE).is_file() and saved != stats
    record = json.loads((run_dir / STREAM_NORMALISATION_FILE).read_text())
    assert record["data_fingerprint"] == run.data_fingerprint


# -- Python API ------------------------------------------------------------------------------------
def test_load_run_from_the_package(bi_run, synth_dir):
    run = multitask.load_run(bi_run)
    assert run.config == _config(synth_dir, bidirectional=True) and run.variant == "APoc"
    kinematics, truth = _held_out(synth_dir)
    from_path, from_array = run.predict(kinematics), run.predict(read_kinematics(kinematics))
    assert from_path.table().equals(from_array.table()) and len(from_path.table()) == len(truth)
    with pytest.raises(ValueError, match=r"expected \[frames, 76\]"):
        run.predict(np.zeros((100, 14)))


# -- multitask-export ------------------------------------------------------------------------------
_FRESH_PROCESS = """
import sys
import numpy as np
import tensorflow as tf
model = tf.saved_model.load(sys.argv[1])
kinematics = np.loadtxt(sys.argv[2], ndmin=2)
out = model.signatures["serving_default"](kinematics=tf.constant(kinematics))
ours = {"jigsaws_tools", "rnn_seg", "baseline", "multitask"}
assert not ours & {name.split(".")[0] for name in sys.modules}, "imported this project"
np.savez(sys.argv[3], **{name: value.numpy() for name, value in out.items()})
"""


@pytest.mark.slow
def test_exported_model_alone_reproduces_multitask_predict(bi_run, synth_dir, tmp_path):
    kinematics, _ = _held_out(synth_dir)
    assert predict_main([str(bi_run), str(kinematics), "--out", str(tmp_path / "pred"),
                         "--no-plots"]) == 0
    assert export_main([str(bi_run), "--out", str(tmp_path / "saved")]) == 0
    loaded = subprocess.run([sys.executable, "-c", _FRESH_PROCESS, str(tmp_path / "saved"),
                             str(kinematics), str(tmp_path / "out.npz")],
                            check=True, cwd=tmp_path, capture_output=True, text=True,
                            env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    assert "custom gradients" not in loaded.stderr, loaded.stderr     # a user's load is quiet
    exported = np.load(tmp_path / "out.npz")
    table = pd.read_csv(tmp_path / "pred" / f"{kinematics.stem}.csv")
    np.testing.assert_array_equal(exported["frame"], table["frame"])
    np.testing.assert_array_equal(exported["sample"], table["sample"])
    np.testing.assert_array_equal(np.asarray(GESTURES)[exported["gesture"]], table["gesture"])
    np.testing.assert_array_equal(np.asarray(SUTURING.stage_names)[exported["progress"]],
                                  table["progress"])
    for task, prefix in (("gesture", "gesture_p_"), ("progress", "progress_y")):
        np.testing.assert_allclose(exported[f"{task}_scores"], table.filter(like=prefix),
                                   atol=1e-5)              # the CSV's 5 decimals, float32 outputs
    description = json.loads((tmp_path / "saved" / "assets.extra" / "model.json").read_text())
    assert description["tasks"]["gesture"]["classes"] == list(GESTURES)
    assert list(description["tasks"]) == ["gesture", "progress"]
    for signature in description["signatures"].values():     # every path it names is there
        for text in signature["outputs"].values():
            for task, key in re.findall(r"\btasks\.(\w+)\.(\w+)", text):
                assert key in description["tasks"][task], text
    assert description["preprocessing"]["feature_columns_1based"][:3] == [39, 40, 41]
    assert export_main([str(bi_run), "--out", str(tmp_path / "saved")]) == 2
    model = tf.saved_model.load(str(tmp_path / "saved"))
    broken = read_kinematics(kinematics)
    broken[40, 3] = np.nan
    with pytest.raises(tf.errors.InvalidArgumentError, match="non-finite"):
        model.signatures["serving_default"](kinematics=tf.constant(broken))


def test_graph_scores_and_decoding_agree_with_numpy():
    rng = np.random.default_rng(0)
    for task in [*get_variant("APr").tasks(), *get_variant("APc").tasks(),
                 *get_variant("APoc").tasks()]:
        outputs = rng.normal(0, 3, (200, task.num_outputs)).astype(np.float32)
        outputs[:5] = 0.0                                           # ties and the 0.5 boundary
        np.testing.assert_allclose(task.scores_tf(tf.constant(outputs)).numpy(),
                                   task.scores(outputs), rtol=1e-5, atol=1e-6)
        np.testing.assert_array_equal(task.decode_tf(tf.constant(outputs)).numpy(),
                                      task.decode(outputs))


@pytest.mark.parametrize("main", [predict_main, evaluate_main, export_main])
def test_commands_have_version_and_help(main, capsys):
    for flag in ("--version", "--help"):
        with pytest.raises(SystemExit) as done:
            main([flag])
        assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("multitask-") and "--checkpoint N" in out and "default" in out


def test_inputs_expand_folders_and_refuse_name_clashes(synth_dir, tmp_path):
    release = kinematics_files([synth_dir])
    assert len(release) == 40 and release[0].parent == kinematics_dir(synth_dir)
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x.txt").write_text("0\n")
    (tmp_path / "x.txt").write_text("0\n")
    assert kinematics_files([tmp_path / "a"]) == [tmp_path / "a" / "x.txt"]
    with pytest.raises(ValueError, match="two inputs would write x.csv"):
        kinematics_files([tmp_path / "a", tmp_path / "x.txt"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=r"no kinematics files \(\*\.txt\)"):
        kinematics_files([tmp_path / "empty"])


def test_an_unfinished_run_loads_with_a_warning(bi_run, tmp_path, caplog):
    run_dir = tmp_path / "run"
    shutil.copytree(bi_run, run_dir)
    (run_dir / "finished.json").unlink()
    run = load_run(run_dir, checkpoint=min(checkpoint_sweeps(run_dir)))
    assert not run.finished and run.checkpoint == min(checkpoint_sweeps(run_dir))
    assert "unfinished" in caplog.text


@pytest.mark.slow
def test_predict_evaluate_and_export_replace_earlier_output_all_or_nothing(
        bi_run, fw_run, synth_dir, tmp_path, monkeypatch):
    """Over an earlier output, each command killed at any step of its publish (its place copied
    there, as a SIGKILL leaves it) shows the earlier output or the new one, whole: a folder
    written whole at every instant, the files of a prediction once the next call has finished
    the journalled moves; before that, a prediction.json describes its own CSVs or is absent
    (issue 66: never the new record beside an old CSV)."""
    from test_publish import observed_steps, visible

    from rnn_seg.runs import publish
    from rnn_seg.runs.lock import hold_folder
    from rnn_seg.runs.manifest import finish_pending

    first, second = (str(kinematics_dir(synth_dir) / f"Suturing_{n}.txt") for n in ("B002", "B003"))
    labels, scores = tmp_path / "labels", tmp_path / "scores" / "B"
    exported = tmp_path / "exp" / "A"
    commands = {  # place observed, the earlier output, the new one over it
        "predict": (labels, [predict_main, str(bi_run), first, "--out", str(labels), "--no-plots"],
                    [predict_main, str(bi_run), second, "--out", str(labels), "--no-plots",
                     "--overwrite"]),
        "evaluate": (scores.parent, [evaluate_main, str(bi_run), "--out", str(scores),
                                     "--no-plots", "--test-user", "C"],
                     [evaluate_main, str(bi_run), "--out", str(scores), "--no-plots",
                      "--overwrite"]),
        "export": (exported.parent, [export_main, str(fw_run), "--out", str(exported)],
                   [export_main, str(bi_run), "--out", str(exported), "--overwrite"])}
    for name, (place, earlier, later) in commands.items():
        assert earlier[0](earlier[1:]) == 0
        output = labels if name == "predict" else place / (scores if name == "evaluate"
                                                            else exported).name
        old = visible(output)
        taken = observed_steps(monkeypatch, place, tmp_path / "killed" / name)
        assert later[0](later[1:]) == 0
        monkeypatch.setattr(publish, "step_hook", lambda step: None)
        new = visible(output)
        assert old != new and taken, name
        for step, copy in taken:
            seen = copy if name == "predict" else copy / output.name
            if name == "predict":
                if "prediction.json" in visible(seen):      # a reader who never calls again
                    assert visible(seen) in (old, new), (name, step)
                else:
                    assert any(visible(seen).items() <= output.items()
                               for output in (old, new)), (name, step)
                with hold_folder(copy, "output folder"):
                    finish_pending(copy, "prediction.json")
            else:
                assert visible(seen) in (old, new), (name, step)
                with publish.claimed(seen):
                    pass
            assert visible(seen) in (old, new), (name, step)
            assert not [p for p in copy.iterdir() if p.name.endswith(".tmp")
                        or p.name.startswith(".partial-")], (name, step)


def test_a_full_disk_during_export_is_one_line_and_leaves_the_earlier_export(
        bi_run, tmp_path, capsys, monkeypatch):
    """TensorFlow's own error of a refused write (``ulimit -f``: OutOfRangeError "File too
    large") is one line naming the SavedModel and the space left, no traceback; the earlier
    export stays whole and nothing hidden is left beside it."""
    from test_publish import visible

    out = tmp_path / "exported" / "APoc_B"
    assert export_main([str(bi_run), "--out", str(out)]) == 0
    before = visible(out)

    def refused(*args, **kwargs):
        raise tf.errors.OutOfRangeError(None, None, f"{tmp_path}/x/variables.data; File too large")

    monkeypatch.setattr(tf.saved_model, "save", refused)
    capsys.readouterr()
    assert export_main([str(bi_run), "--out", str(out), "--overwrite"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"cannot write SavedModel {out} (" in err and "File too large" in err
    assert "MB free" in err and "checkpoint" not in err
    assert visible(out) == before
    assert [p.name for p in out.parent.iterdir()] == ["APoc_B"]
