"""What a run costs beyond training: graphs traced once, monitoring that never changes training."""
import json

import numpy as np
import pandas as pd
import pytest

from multitask.models.heads import OrdinalProgress
from rnn_seg.lstm import EncoderConfig
from rnn_seg.model import SegmentationModel
from rnn_seg.optim import OptimConfig
from rnn_seg.stack import TrainerStack
from rnn_seg.tasks import SoftmaxClassification
from rnn_seg.trainer import SequenceSet, TrainConfig, Trainer

F, EPOCHS = 4, 4


def _data(seed: int) -> SequenceSet:
    """Twelve sequences of 12-40 steps: every sweep has another duration."""
    rng = np.random.default_rng(seed)
    inputs = [rng.normal(size=(rng.integers(12, 40), F)).astype(np.float32) for _ in range(12)]
    labels = {"gesture": [(x[:, 0] > 0).astype(int) + (x[:, 1] > 0.5) for x in inputs],
              "progress": [np.minimum(np.arange(len(x)) * 5 // len(x), 4) for x in inputs]}
    return SequenceSet([f"s{i}" for i in range(12)], inputs, labels)


def _trainer(run_dir, seed=0, **train) -> Trainer:
    tasks = [SoftmaxClassification("gesture", ["a", "b", "c"]), OrdinalProgress()]
    model = SegmentationModel(F, EncoderConfig(hidden=8, loops="graph"), tasks, seed)
    config = TrainConfig(seed=seed, eval_points=(EPOCHS - 1, EPOCHS), plots="none", **train)
    return Trainer(model, tasks, OptimConfig(total=EPOCHS, decay_start=2), config, _data(seed),
                   _data(seed + 100), run_dir, {}, 5.0, log=lambda m: None)


def test_a_lone_run_traces_each_graph_once(tmp_path):
    trainer = _trainer(tmp_path / "run", monitor_every=1, monitor_train=True)
    trainer.run()
    assert trainer._train_step.experimental_get_tracing_count() == 1
    assert trainer.model.infer.experimental_get_tracing_count() == 1
    timing = json.loads((tmp_path / "run" / "timing.json").read_text())
    assert {"trace", "train", "monitor", "evaluate", "checkpoint"} <= set(timing)


def test_compiled_loops_are_how_a_run_computes_not_what(tmp_path):
    """A run folder and a grid accept either loops: same settings, same grid."""
    from dataclasses import replace

    from multitask.grid.folder import comparable_spec as _canonical
    from multitask.grid.spec import GridSpec, spec_payload
    from rnn_seg.runs.settings import settings_hash

    graph = {"encoder": EncoderConfig(hidden=8), "tasks": ["gesture"]}
    xla = {**graph, "encoder": replace(graph["encoder"], loops="xla")}
    assert settings_hash(graph) == settings_hash(xla)
    spec = GridSpec(data_dir="synthetic")
    assert (_canonical(spec_payload(spec))
            == _canonical(spec_payload(replace(spec, loops="xla"))))
    assert _canonical(spec_payload(spec)) != _canonical(spec_payload(replace(spec, hidden=8)))


def test_a_grid_refuses_to_stack_compiled_loops(tmp_path, capsys):
    from multitask.grid.cli import main as grid_main

    code = grid_main(["--preset", "quick", "--data-dir", "synthetic", "--out", str(tmp_path),
                      "--loops", "xla", "--stack", "2"])
    assert code == 2 and "--stack 1 with loops xla" in capsys.readouterr().err


@pytest.mark.slow
def test_a_stack_traces_its_step_once(tmp_path):
    members = [_trainer(tmp_path / f"m{s}", seed=s, monitor_every=1) for s in (0, 1)]
    stack = TrainerStack(members)
    stack.run()
    assert len(stack.compiled_steps) == 1
    assert all(step.experimental_get_tracing_count() == 1 for step in stack.compiled_steps.values())
    assert all(m.model.infer.experimental_get_tracing_count() == 1 for m in members)


@pytest.mark.slow
def test_monitoring_never_changes_training(tmp_path):
    quiet = _trainer(tmp_path / "quiet", monitor_every=100)
    busy = _trainer(tmp_path / "busy", monitor_every=1, monitor_train=True)
    quiet.run()
    busy.run()
    for a, b in zip(quiet.variables, busy.variables):
        np.testing.assert_array_equal(a.numpy(), b.numpy())
    assert (json.loads((tmp_path / "quiet/metrics.json").read_text())
            == json.loads((tmp_path / "busy/metrics.json").read_text()))


def test_history_scores_only_on_monitored_units(tmp_path):
    _trainer(tmp_path / "run", monitor_every=3).run()
    history = pd.read_csv(tmp_path / "run" / "history.csv")
    assert list(history["n"]) == [1, 2, 3, 4]
    assert history[["loss_gesture", "loss_progress", "unit_seconds"]].notna().all().all()
    monitored = history["test_gesture_acc"].notna().tolist()
    assert monitored == [False, False, True, True]         # every 3 units and the last
    train = history.filter(like="train_")          # columns fixed per run (#29), cells empty
    assert len(train.columns) == 4 and train.isna().all().all()


@pytest.mark.parametrize("tensorboard", [True, False])
def test_tensorboard_scalars_are_optional(tmp_path, tensorboard):
    _trainer(tmp_path / "run", tensorboard=tensorboard).run()
    events = list((tmp_path / "run").glob("tensorboard/events.out.tfevents.*"))
    assert bool(events) == tensorboard
    if tensorboard:
        import tensorflow as tf

        values = [v for event in tf.compat.v1.train.summary_iterator(str(events[0]))
                  for v in event.summary.value]
        losses = [v for v in values if v.tag == "loss/gesture"]
        assert len(losses) == EPOCHS
        assert losses[0].metadata.plugin_data.plugin_name == "scalars"
        assert np.isfinite(tf.make_ndarray(losses[0].tensor))


def test_thread_plan_gives_each_direction_a_core_when_the_weights_fit_the_cache():
    from rnn_seg.threads import thread_plan

    small_cache, large_cache = 32 * 2**20, 480 * 2**20
    assert thread_plan(2, 1024, "fp32", small_cache) == (2, 1)      # 2 x 16 MB would evict
    assert thread_plan(2, 1024, "bf16", small_cache) == (1, 2)      # 2 x 8 MB fit half of it
    assert thread_plan(2, 1024, "fp32", large_cache) == (1, 2)
    assert thread_plan(2, 128, "fp32", small_cache) == (1, 2)
    assert thread_plan(1, 128) == (1, 1)
    assert thread_plan(2, 128, bidirectional=False) == (2, 1)           # one loop: both cores in it


def test_progress_lines_say_what_their_numbers_are(tmp_path):
    lines = []
    trainer = _trainer(tmp_path / "run", monitor_every=2, monitor_train=True)
    trainer.log = lines.append
    trainer.run()
    progress = [line for line in lines if line.startswith("[run] epoch")]
    assert len(progress) == EPOCHS
    assert "loss gesture" in progress[0] and "acc/edit" not in progress[0]
    assert "train acc/edit gesture" in progress[1] and "test acc/edit gesture" in progress[1]
    assert all(" s/epoch  ETA " in line for line in progress)


@pytest.mark.slow
def test_the_first_lines_eta_leaves_out_the_sessions_first_sweep(tmp_path, monkeypatch):
    """TensorFlow's one-off work lands in a session's first sweep (here 10 s, then 1 s a sweep,
    on a clock that moves only while a sweep trains). The first line measures its epoch as it
    was (12 s for 3 sweeps) but gives the time left at the pace of the sweeps after the first:
    9 sweeps left, 9 s, not 3 epochs at 12 s; later lines keep their own pace."""
    import types

    import rnn_seg.trainer

    clock = {"now": 1000.0}
    monkeypatch.setattr(rnn_seg.trainer, "time", types.SimpleNamespace(time=lambda: clock["now"]))
    lines = []
    trainer = _trainer(tmp_path / "run")
    trainer.log = lines.append
    step = trainer.step

    def timed(sweep, learning_rate):
        clock["now"] += 10.0 if sweep == 0 else 1.0
        return step(sweep, learning_rate)

    monkeypatch.setattr(trainer, "step", timed)
    trainer.run()
    progress = [line for line in lines if line.startswith("[run] epoch")]
    assert trainer.sweeps_per_unit == 3 and len(progress) == EPOCHS
    assert progress[0].endswith("12.0 s/epoch  ETA 0:00:09")
    assert progress[1].endswith("3.0 s/epoch  ETA 0:00:06")
