"""Progress heads, GradNorm, the variants, and A through multitask-train == baseline-train."""
import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
import tensorflow as tf

from baseline.cli import main as baseline_main
from baseline.config import RunConfig
from jigsaws_tools.dataset import DataConfig, load_dataset
from jigsaws_tools.task_definition import SUTURING
from multitask.train_cli import main as multitask_main
from multitask.models.gradnorm import GradNormConfig, GradNormTrainer, shared_layer_variables
from multitask.models.heads import OrdinalProgress, ProgressClassification, ProgressRegression
from multitask.models.fold_run import train_variant
from multitask.models.variants import VARIANTS, get_variant
from rnn_seg.lstm import EncoderConfig
from rnn_seg.model import SegmentationModel
from rnn_seg.optim import OptimConfig
from rnn_seg.tasks import SoftmaxClassification
from rnn_seg.trainer import SequenceSet, TrainConfig


# -- heads on hand-made sequences ------------------------------------------------------------------
def test_regression_rounding_clipping_and_normalised_mae():
    head = ProgressRegression()
    out = np.array([[-0.7], [0.4], [0.6], [2.5], [3.49], [5.2]])
    np.testing.assert_array_equal(head.decode(out), [0, 0, 1, 2, 3, 4])
    truth = np.array([0, 0, 1, 2, 3, 4])
    m = head.extra_metrics([out], [truth])
    assert m["mae_normalised"] == pytest.approx(100 * np.mean(np.abs(out[:, 0] - truth)) / 4)
    assert m["mae_normalised_rounded"] == 0.0
    loss = head.loss(tf.constant(out[None], tf.float32), tf.constant(head.encode(truth)[None]))
    assert float(loss) == pytest.approx(np.mean(np.abs(out[:, 0] - truth)), rel=1e-5)


def test_ordinal_head_targets_loss_and_decoding():
    head = OrdinalProgress(reduction="mean")
    stages = np.array([0, 3, 4])
    targets = head.encode(stages)
    assert targets.shape == (3, 5) and targets[1].tolist() == [1, 1, 1, 1, 0]
    logits = np.where(targets > 0, 4.0, -4.0)
    np.testing.assert_array_equal(head.decode(logits), stages)
    loss = float(head.loss(tf.constant(logits[None], tf.float32), tf.constant(targets[None])))
    assert loss == pytest.approx(np.log1p(np.exp(-4.0)), rel=1e-5)


def test_summed_ordinal_loss_is_the_paper_mbce():
    """Binary cross-entropy summed over the 5 outputs, averaged over time steps (paper Eq. 2)."""
    logits = np.array([[[2.0, -1.0, 0.5, -3.0, 0.0],
                        [1.0, 1.0, -2.0, 0.3, -0.7]]])                  # [B=1, T=2, 5]
    stages = np.array([[2, 0]])
    targets = OrdinalProgress().encode(stages)                          # [[1,1,1,0,0],[1,0,0,0,0]]
    p = 1 / (1 + np.exp(-logits))
    bce = -(targets * np.log(p) + (1 - targets) * np.log(1 - p))
    by_hand = bce.sum(axis=-1).mean()
    summed = OrdinalProgress(reduction="sum").loss(tf.constant(logits, tf.float32), tf.constant(targets))
    assert float(summed) == pytest.approx(by_hand, rel=1e-5)
    averaged = OrdinalProgress(reduction="mean").loss(tf.constant(logits, tf.float32), tf.constant(targets))
    assert float(averaged) == pytest.approx(by_hand / 5, rel=1e-5)
    mask = tf.constant([[True, False]])
    assert float(OrdinalProgress().loss(tf.constant(logits, tf.float32), tf.constant(targets),
                                        mask)) == pytest.approx(bce[0, 0].sum(), rel=1e-5)
    assert OrdinalProgress().reduction == "sum"                          # the default


def test_classification_head():
    head = ProgressClassification()
    assert head.num_outputs == 5 and head.ordered
    np.testing.assert_array_equal(head.decode(np.eye(5)[[2, 4]] * 3), [2, 4])


# -- GradNorm on a small two-task problem -----------------------------------------------------------
class _Scaled(SoftmaxClassification):
    """A softmax task whose loss is multiplied by ``scale``."""

    def __init__(self, name, scale):
        super().__init__(name, ["a", "b", "c"])
        self.scale = scale

    def loss(self, outputs, targets, mask=None):
        return self.scale * super().loss(outputs, targets, mask)


def _two_task_trainer(tmp_path, alpha, seed=0, weight_lr=0.025, relative_rate="chen"):
    rng = np.random.default_rng(seed)
    inputs = [rng.normal(size=(40, 4)).astype(np.float32) for _ in range(10)]
    labels = {"t1": [(x[:, 0] > 0).astype(int) + (x[:, 1] > 1) for x in inputs],
              "t2": [(x[:, 2] > 0).astype(int) * 2 for x in inputs]}
    data = SequenceSet([f"s{i}" for i in range(10)], inputs, labels)
    tasks = [_Scaled("t1", 1.0), _Scaled("t2", 100.0)]
    model = SegmentationModel(4, EncoderConfig(hidden=8, keep_prob=1.0), tasks, seed)
    return GradNormTrainer(model, tasks, OptimConfig(learning_rate=0.1, unit="sweeps", total=60,
                                                     decay_start=60),
                           TrainConfig(eval_points=(60,), plots="none"), data, data, tmp_path, {},
                           5.0, log=lambda m: None,
                           gradnorm=GradNormConfig(alpha=alpha, learning_rate=weight_lr,
                                                   relative_rate=relative_rate))


def _direct_norms(trainer, sweep):
    """||grad_W (w_i L_i)|| with one tape per task, no dropout differences (keep_prob 1)."""
    inputs, resets, targets, _ = trainer.batch(sweep)
    weights = trainer.weights.numpy()
    norms = []
    for i, task in enumerate(trainer.tasks):
        with tf.GradientTape() as tape:
            out = trainer.model(inputs, resets, None)
            loss = weights[i] * task.loss(out[task.name], targets[i])
        norms.append(float(tf.linalg.global_norm(tape.gradient(loss, trainer.shared))))
    return np.array(norms)


def test_gradnorm_balances_a_task_scaled_100x(tmp_path):
    trainer = _two_task_trainer(tmp_path, alpha=1.5)
    assert {id(v) for v in trainer.shared} == {id(v) for v in shared_layer_variables(trainer.model)}
    G0 = _direct_norms(trainer, 0)
    out = trainer.step(0, 0.1)
    np.testing.assert_allclose(out[1], G0, rtol=1e-3)          # G_i as with separate tapes
    assert G0[1] > 20 * G0[0]
    for sweep in range(1, 60):
        trainer.record(trainer.step(sweep, 0.1))
        w = trainer.weights.numpy()
        assert np.all(w > 0) and w.sum() == pytest.approx(2.0, abs=1e-5)
    assert w[1] < 0.5 < 1.5 < w[0]                              # the 100x task is down-weighted
    G_end = _direct_norms(trainer, 60)
    assert G_end[1] / G_end[0] < G0[1] / G0[0] / 2            # norms move towards balance


@pytest.mark.parametrize("relative_rate", ["chen", "paper"])
def test_gradnorm_relative_inverse_training_rate(tmp_path, relative_rate):
    """r_i = (L_i / L_i(0)) / mean of the ratios (Chen et al.) or / mean loss (the paper's text)."""
    trainer = _two_task_trainer(tmp_path, alpha=1.5, relative_rate=relative_rate)
    trainer.step(0, 0.1)
    losses, _, r, _ = trainer.step(1, 0.1)
    ratio = losses / trainer.initial_losses.numpy()
    expected = ratio / (ratio.mean() if relative_rate == "chen" else losses.mean())
    np.testing.assert_allclose(r, expected, rtol=1e-5)


def test_gradnorm_alpha_zero_equalises_norms(tmp_path):
    """With alpha = 0 the target is the mean norm; a weight step fine enough to resolve the ~0.02
    weight that balances a 100x task lets the norms meet."""
    trainer = _two_task_trainer(tmp_path, alpha=0.0, weight_lr=0.001)
    for sweep in range(300):
        trainer.record(trainer.step(sweep, 0.02))
    G = np.mean([g for g, _, _ in trainer._stats[-40:]], axis=0)
    assert abs(G[1] / G[0] - 1.0) < 0.3, G


# -- variants ----------------------------------------------------------------------------------------
def test_registry_and_paper_optimisers():
    assert list(VARIANTS) == ["A", "APr", "APc", "APoc", "Pr", "Pc", "Poc"]
    apr, apc = get_variant("APr").optim(), get_variant("APc").optim()
    assert (apr.learning_rate, apr.momentum) == (0.1, 0.9) and (apc.learning_rate, apc.momentum) == (1.0, 0.0)
    assert (apr.decay_start, apr.total) == (80, 120)
    pc = get_variant("Pc").optim()
    assert pc.total == 80 and pc.decay_start < 80 and pc.learning_rate == apc.learning_rate
    assert get_variant("Pc").eval_points()[-1] == 80
    with pytest.raises(ValueError, match="unknown variant"):
        get_variant("XYZ")


def _run_config(synth_dir, optim, epochs=14, hidden=48):
    return RunConfig(data=DataConfig(str(synth_dir)), test_user="C",
                     encoder=EncoderConfig(hidden=hidden),
                     optim=replace(optim, total=epochs, decay_start=(2 * epochs) // 3),
                     train=TrainConfig(eval_points=(epochs,), plots="none"))


def _chance(trials, field):
    labels = np.concatenate([getattr(t, field) for t in trials])
    return 100.0 * np.bincount(labels).max() / len(labels)


@pytest.mark.parametrize("name,weighting", [("APr", "gradnorm"), ("APc", "fixed"),
                                            ("APoc", "gradnorm"), ("Pc", "fixed"),
                                            ("Poc", "fixed"), ("Pr", "fixed")])
@pytest.mark.slow
def test_variant_learns_on_held_out_user(synth_dir, tmp_path, name, weighting):
    variant = get_variant(name)
    config = _run_config(synth_dir, variant.optim())
    result = train_variant(variant, weighting, config, tmp_path / name, log=lambda m: None)
    _, test = load_dataset(config.data).louo_split("C")
    progress = result["mean"]["progress"]
    assert progress["accuracy"] > _chance(test, "progress") + 20, progress
    if variant.gestures:
        assert result["mean"]["gesture"]["accuracy"] > _chance(test, "gestures") + 25
    if name == "APr":
        assert "mae_normalised" in progress and progress["mae_normalised"] < 20
    if weighting == "gradnorm":
        log = pd.read_csv(tmp_path / name / "gradnorm.csv")
        assert {"w_gesture", "w_progress", "G_gesture", "r_progress"} <= set(log.columns)
        np.testing.assert_allclose(log["w_end_gesture"] + log["w_end_progress"], 2.0, atol=1e-4)


def test_gradnorm_needs_two_tasks(synth_dir, tmp_path):
    with pytest.raises(ValueError, match="two tasks"):
        train_variant(get_variant("Pc"), "gradnorm", _run_config(synth_dir, OptimConfig()), tmp_path)


def test_variant_a_equals_baseline_train(synth_dir, tmp_path, monkeypatch):
    monkeypatch.setenv("JIGSAWS_DIR", str(synth_dir))
    common = ["--hidden", "32", "--epochs", "3", "--seed", "5", "--test-user", "D", "--no-plots"]
    assert baseline_main(common + ["--out", str(tmp_path / "base")]) == 0
    assert multitask_main(common + ["--variant", "A", "--weighting", "fixed",
                                    "--out", str(tmp_path / "mt")]) == 0
    base = sorted((tmp_path / "base/eval/epoch0003/predictions").glob("*.csv"))
    assert base
    for csv in base:
        a = pd.read_csv(csv)
        b = pd.read_csv(tmp_path / "mt/eval/epoch0003/predictions" / csv.name)
        pd.testing.assert_frame_equal(a, b)


@pytest.mark.slow
def test_multitask_cli_outputs_progress_columns_and_plots(synth_dir, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("JIGSAWS_DIR", str(synth_dir))
    out = tmp_path / "apoc"
    assert multitask_main(["--variant", "APoc", "--weighting", "gradnorm", "--hidden", "16",
                           "--epochs", "2", "--eval-at", "1,2", "--test-user", "E",
                           "--out", str(out)]) == 0
    assert "progress: accuracy" in capsys.readouterr().out
    table = pd.read_csv(next((out / "eval/epoch0002/predictions").glob("*.csv")))
    stages = SUTURING.stage_names
    assert {"progress", "progress_true", "gesture_p_G11"} <= set(table.columns)
    assert [c for c in table.columns if c.startswith("progress_y")] == [f"progress_y_{s}"
                                                                          for s in stages]
    assert set(table["progress"]) | set(table["progress_true"]) <= set(stages)
    assert len(list((out / "eval/epoch0002/plots").glob("*.png"))) == 5
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics["mean"]) == {"gesture", "progress"} and set(metrics["points"]) == {"1", "2"}
    config = json.loads((out / "config.json").read_text())
    assert config["variant"] == "APoc" and config["gradnorm"]["alpha"] == 1.5
