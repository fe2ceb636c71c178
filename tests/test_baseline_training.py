"""Model A trains, writes its outputs, resumes after interruption, and runs at paper size."""
import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from baseline.cli import main as baseline_main
from baseline.config import RunConfig
from baseline.builder import train_baseline
from jigsaws_tools.dataset import DataConfig, load_dataset
from jigsaws_tools.gestures import GESTURES
from rnn_seg.lstm import EncoderConfig
from rnn_seg.optim import OptimConfig
from rnn_seg.runs.folder import is_finished
from rnn_seg.trainer import Trainer, TrainConfig


def _config(data_dir, epochs=12, hidden=32, eval_points=(), bidirectional=True, **train):
    return RunConfig(data=DataConfig(str(data_dir)), test_user="B",
                     encoder=EncoderConfig(hidden=hidden, bidirectional=bidirectional),
                     optim=OptimConfig(total=epochs, decay_start=(2 * epochs) // 3, decay_every=100),
                     train=TrainConfig(seed=0, eval_points=eval_points, **train))


def _majority_accuracy(trials):
    gestures = np.concatenate([t.gestures for t in trials])
    return 100.0 * np.bincount(gestures).max() / len(gestures)


@pytest.mark.parametrize("bidirectional", [True, False])
@pytest.mark.slow
def test_model_a_beats_majority_on_held_out_user(synth_dir, tmp_path, bidirectional):
    config = _config(synth_dir, bidirectional=bidirectional)
    result = train_baseline(config, tmp_path / "run", log=lambda m: None)
    _, test = load_dataset(config.data).louo_split("B")
    chance = _majority_accuracy(test)
    assert result["mean"]["gesture"]["accuracy"] > chance + 30, (result["mean"], chance)


def test_an_inner_run_neither_trains_nor_tests_on_its_held_out_user(synth_dir, tmp_path):
    """A validation run inside outer fold B: user C is scored, B is in neither set."""
    from baseline.builder import build_trainer, gesture_task
    from jigsaws_tools.errors import JigsawsError

    config = replace(_config(synth_dir, epochs=1), test_user="C", held_out_users=("B",))
    dataset = load_dataset(config.data)
    trainer = build_trainer(config, [gesture_task()], tmp_path / "run", dataset,
                            log=lambda m: None)
    users = lambda names: {n.rsplit("_", 1)[-1][0] for n in names}
    assert users(trainer.test.names) == {"C"}
    assert users(trainer.train.names) == set(dataset.users) - {"B", "C"}
    with pytest.raises(JigsawsError, match="unknown held-out user 'Z'"):
        dataset.louo_split("C", ("Z",))
    with pytest.raises(JigsawsError, match="no training user left"):
        dataset.louo_split("C", tuple(u for u in dataset.users if u != "C"))


def test_run_outputs(synth_dir, tmp_path):
    run = tmp_path / "run"
    train_baseline(_config(synth_dir, epochs=3, eval_points=(2, 3), plots="all"), run,
                   log=lambda m: None)
    assert is_finished(run)
    config = json.loads((run / "config.json").read_text())
    assert config["run"]["encoder"]["hidden"] == 32 and config["tasks"] == ["gesture"]
    metrics = json.loads((run / "metrics.json").read_text())
    assert set(metrics["points"]) == {"2", "3"}
    assert metrics["mean"]["gesture"]["accuracy"] == pytest.approx(
        np.mean([metrics["points"][p]["gesture"]["accuracy"] for p in ("2", "3")]))
    for point in ("epoch0002", "epoch0003"):
        csvs = sorted((run / "eval" / point / "predictions").glob("*.csv"))
        assert [p.stem for p in csvs] == [f"Suturing_B00{i}" for i in range(1, 6)]
        table = pd.read_csv(csvs[0])
        assert list(table.columns[:5]) == ["frame", "time_s", "sample", "gesture", "gesture_true"]
        assert list(table["sample"]) == list(range(len(table)))      # one row per 5 Hz sample
        np.testing.assert_allclose(table["time_s"], (table["frame"] - 1) / 30, atol=1e-5)
        assert set(table["gesture"]) | set(table["gesture_true"]) <= set(GESTURES)
        np.testing.assert_allclose(table.filter(like="gesture_p_").sum(axis=1), 1.0, atol=1e-3)
        assert len(list((run / "eval" / point / "plots").glob("*.png"))) == 5
    history = pd.read_csv(run / "history.csv")
    assert list(history["n"]) == [1, 2, 3]
    assert list((run / "checkpoints").glob("ckpt-*.index"))


class _Interrupt(Exception):
    pass


def _interrupted_at_epoch_3(config, run, monkeypatch):
    """Train ``config`` into ``run`` and stop it after epoch 3's progress row, before its
    checkpoint, as a killed process would."""
    original = Trainer._log_progress

    def crash_at_epoch_3(self, done, *args):
        original(self, done, *args)
        if done == 3 * self.sweeps_per_epoch:
            raise _Interrupt

    with monkeypatch.context() as patch:
        patch.setattr(Trainer, "_log_progress", crash_at_epoch_3)
        with pytest.raises(_Interrupt):
            train_baseline(config, run, log=lambda m: None)


@pytest.mark.slow
def test_resume_after_interruption_matches_uninterrupted(synth_dir, tmp_path, monkeypatch):
    config = _config(synth_dir, epochs=4, eval_points=(4,), plots="none")
    straight = tmp_path / "straight"
    train_baseline(config, straight, log=lambda m: None)

    resumed = tmp_path / "resumed"
    _interrupted_at_epoch_3(config, resumed, monkeypatch)
    assert not is_finished(resumed) and not (resumed / "metrics.json").exists()
    assert list(pd.read_csv(resumed / "history.csv")["n"]) == [1, 2, 3]
    messages = []
    train_baseline(config, resumed, log=messages.append)
    assert any("resuming from sweep" in m for m in messages)
    assert list(pd.read_csv(resumed / "history.csv")["n"]) == [1, 2, 3, 4]
    for csv in (straight / "eval/epoch0004/predictions").glob("*.csv"):
        a, b = pd.read_csv(csv), pd.read_csv(resumed / "eval/epoch0004/predictions" / csv.name)
        pd.testing.assert_frame_equal(a, b, atol=1e-4)      # names equal, scores close
    # a finished run is not trained again
    messages.clear()
    train_baseline(config, resumed, log=messages.append)
    assert messages == [f"{resumed}: already finished"]


def test_a_resumed_runs_time_counts_its_earlier_sessions_once(synth_dir, tmp_path, monkeypatch):
    config = _config(synth_dir, epochs=4, eval_points=(4,), plots="none")
    run = tmp_path / "run"
    _interrupted_at_epoch_3(config, run, monkeypatch)
    clocks = sorted((run / "checkpoints").glob("ckpt-*.clock.json"),
                    key=lambda path: int(path.name.split(".")[0].removeprefix("ckpt-")))
    assert clocks and not is_finished(run)
    # as if the session up to the checkpoint the run resumes from had taken an hour
    saved = json.loads(clocks[-1].read_text())
    clocks[-1].write_text(json.dumps({"phases": {**saved["phases"], "train": 3600.0},
                                      "elapsed_seconds": 3600.0}))
    messages = []
    train_baseline(config, run, log=messages.append)
    assert 3600 < json.loads((run / "timing.json").read_text())["train"] < 2 * 3600
    elapsed = pd.read_csv(run / "history.csv").elapsed_seconds
    assert elapsed.is_monotonic_increasing and 3600 < elapsed.iloc[-1] < 2 * 3600
    assert not any("predates the clock" in m for m in messages)
    kept = (run / "checkpoints").glob
    assert len(list(kept("ckpt-*.clock.json"))) == len(list(kept("ckpt-*.index")))  # pruned alike


def test_a_checkpoint_without_its_clock_resumes_and_says_so(synth_dir, tmp_path, monkeypatch):
    config = _config(synth_dir, epochs=4, eval_points=(4,), plots="none")
    run = tmp_path / "run"
    _interrupted_at_epoch_3(config, run, monkeypatch)
    for clock in (run / "checkpoints").glob("ckpt-*.clock.json"):
        clock.unlink()                                   # as a run begun by an older version
    messages = []
    train_baseline(config, run, log=messages.append)
    assert is_finished(run) and any("predates the clock" in m for m in messages)


def test_cli_reports_bad_input(tmp_path, capsys):
    assert baseline_main(["--data-dir", str(tmp_path / "nope"), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("baseline-train: error: ") and "not found" in err
    assert "Traceback" not in err
    assert baseline_main(["-v", "--data-dir", str(tmp_path / "nope"), "--out",
                          str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err                 # -v: the traceback, then the same line
    assert "Traceback" in err and "baseline-train: error: " in err and "not found" in err
