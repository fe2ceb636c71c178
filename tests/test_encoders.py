"""The temporal-convolution encoders: shapes, receptive fields, padding, MS-TCN's stages and
losses, GradNorm on them, the optimisers, learning on a held-out user, and the commands."""
import json
from dataclasses import replace

import numpy as np
import pytest
import tensorflow as tf

from baseline.config import RunConfig
from jigsaws_tools.dataset import DataConfig, load_dataset
from jigsaws_tools.preprocessing import PreprocessConfig
from multitask.evidence.statistics.time_baseline import chance_accuracy
from multitask.grid.folder import comparable_spec
from multitask.grid.spec import RunKey, run_config, spec_from_dict, spec_payload
from multitask.inference.evaluate_cli import main as evaluate_main
from multitask.inference.export_cli import main as export_main
from multitask.inference.predict_cli import main as predict_main
from multitask.inference.trained_run import load_run
from multitask.models.fold_run import train_variant
from multitask.models.gradnorm import GradNormConfig, GradNormTrainer
from multitask.models.heads import OrdinalProgress, ProgressClassification, ProgressRegression
from multitask.models.variants import VARIANTS, get_variant
from multitask.train_cli import main as multitask_main
from rnn_seg.config import EncoderConfig, OptimConfig, TrainConfig
from rnn_seg.encoders.config import EDTCNConfig, MSTCNConfig
from rnn_seg.encoders.ms_tcn import smoothing, stage_loss
from rnn_seg.model import SegmentationModel
from rnn_seg.optim import ADAM_BETAS, ADAM_EPSILON, RMSPROP_EPSILON, RMSPROP_RHO, build_optimizer
from rnn_seg.stack import TrainerStack
from rnn_seg.tasks import SoftmaxClassification
from rnn_seg.trainer import SequenceSet, Trainer

F, T = 6, 45
GESTURES = SoftmaxClassification("gesture", list("abcd"))


def _small(kind, causal=False):
    if kind == "ed-tcn":
        return EDTCNConfig(filters=(8, 12), kernel=5, causal=causal)
    return MSTCNConfig(stages=3, layers=4, filters=8, causal=causal)


ENCODERS = [("ed-tcn", False), ("ed-tcn", True), ("ms-tcn", False), ("ms-tcn", True)]


def _model(kind, causal=False, tasks=(GESTURES,), seed=0):
    return SegmentationModel(F, _small(kind, causal), list(tasks), seed)


def _inputs(batch=2, steps=T, seed=1):
    return tf.constant(np.random.default_rng(seed).normal(size=(batch, steps, F)), tf.float32)


def _no_resets(x):
    return tf.zeros(tf.shape(x)[:2], tf.bool)


@pytest.mark.parametrize("kind,causal", ENCODERS)
def test_output_shape_for_any_length(kind, causal):
    tasks = [GESTURES, OrdinalProgress()]
    model = _model(kind, causal, tasks)
    for steps in (1, 7, T):                     # not multiples of ED-TCN's pooling (4)
        x = _inputs(steps=steps)
        out = model(x, _no_resets(x))
        assert out["gesture"].shape == (2, steps, 4) and out["progress"].shape == (2, steps, 5)
        assert np.all(np.isfinite(out["gesture"].numpy()))


def _changed_steps(model, t0):
    """The steps whose outputs move when input step ``t0`` is perturbed."""
    x = _inputs(batch=1).numpy()
    y = x.copy()
    y[0, t0] += 3.0
    a = model(tf.constant(x), _no_resets(x))["gesture"].numpy()[0]
    b = model(tf.constant(y), _no_resets(y))["gesture"].numpy()[0]
    return np.flatnonzero(np.abs(a - b).max(axis=1) > 1e-6)


@pytest.mark.parametrize("kind", ["ed-tcn", "ms-tcn"])
def test_causal_outputs_never_read_the_future(kind):
    t0 = 20
    changed = _changed_steps(_model(kind, causal=True), t0)
    assert changed.size and changed.min() >= t0                  # nothing before t0
    # MS-TCN answers at once; ED-TCN's pooled pairs reach the output once complete, at most
    # 2**layers - 1 samples later (docs/REPRODUCTION.md)
    latency = 0 if kind == "ms-tcn" else 2 ** len(_small(kind).filters) - 1
    assert changed.min() <= t0 + latency


@pytest.mark.parametrize("kind", ["ed-tcn", "ms-tcn"])
def test_offline_outputs_read_both_sides(kind):
    t0 = 20
    changed = _changed_steps(_model(kind, causal=False), t0)
    assert changed.min() < t0 < changed.max()


def test_ms_tcn_one_stage_sees_its_receptive_field_only():
    config = MSTCNConfig(stages=1, layers=3, filters=8)          # 1 + 2 * 7 = 15 samples
    model = SegmentationModel(F, config, [GESTURES], 0)
    t0, half = 22, (config.receptive_field - 1) // 2
    changed = _changed_steps(model, t0)
    assert changed.min() >= t0 - half and changed.max() <= t0 + half
    assert {t0 - half, t0 + half} <= set(changed)                # and reaches its edges


@pytest.mark.parametrize("kind,causal", ENCODERS)
def test_a_sequence_in_a_padded_sweep_gets_its_outputs_alone(kind, causal):
    """Padding a row to a longer sweep (``valid``) changes none of its valid outputs."""
    model = _model(kind, causal, [GESTURES, ProgressRegression()])
    x = _inputs(batch=1, steps=30)
    alone = model(x, _no_resets(x))
    longer = tf.concat([x, tf.ones([1, 13, F]) * 7.0], axis=1)          # junk after its end
    valid = tf.constant(np.arange(43)[None] < 30)
    padded = model.apply(model.params(), longer, _no_resets(longer), None, valid)
    for name in alone:
        np.testing.assert_allclose(padded[name].numpy()[:, :30], alone[name].numpy(), atol=1e-5)


def test_ms_tcn_heads_at_every_stage_and_losses_summed_with_smoothing():
    tasks = [GESTURES, ProgressRegression()]
    model = _model("ms-tcn", tasks=tasks)
    x = _inputs()
    stages = model.stage_outputs(model.params(), x, _no_resets(x))
    assert len(stages) == 3
    assert all(set(s) == {t.name for t in tasks} for s in stages)      # every head, every stage
    rng = np.random.default_rng(0)
    targets = [tf.constant(t.encode(rng.integers(0, t.num_classes, size=(2, T)))) for t in tasks]
    losses = model.losses(model.params(), tasks, x, _no_resets(x), targets)
    config = model.encoder.config
    by_hand = [sum(float(stage_loss(t, s[t.name], y, None, config)) for s in stages)
               for t, y in zip(tasks, targets)]
    np.testing.assert_allclose(losses.numpy(), by_hand, rtol=1e-5)
    # the smoothing applies to the heads with log-probabilities, not to a regression
    out = stages[0]
    assert float(stage_loss(tasks[1], out["progress"], targets[1], None, config)) == \
        pytest.approx(float(tasks[1].loss(out["progress"], targets[1])))
    ordered = OrdinalProgress()
    y = tf.constant(ordered.encode(np.zeros((2, T), int)))
    z = tf.constant(np.random.default_rng(1).normal(size=(2, T, 5)), tf.float32)
    assert float(stage_loss(ordered, z, y, None, config)) > float(ordered.loss(z, y))
    assert float(stage_loss(tasks[0], out["gesture"], targets[0], None, config)) > \
        float(tasks[0].loss(out["gesture"], targets[0]))


def test_truncated_mse_is_truncated_and_held_on_the_earlier_step():
    logp = tf.Variable([[[0.0], [-1.0], [-10.0]]])                  # [B=1, T=3, K=1]
    with tf.GradientTape() as tape:
        value = smoothing(logp, None, tau=4.0)
    assert float(value) == pytest.approx((1.0 + 16.0) / 2)            # 81 truncated to 16
    grad = tape.gradient(value, logp).numpy()[0, :, 0]
    np.testing.assert_allclose(grad, [0.0, -1.0, 0.0])   # d/d(logp_1) of (logp_1 - c)^2 / 2 only


def test_single_stage_objective_is_exactly_the_task_losses():
    """The LSTM's training loss is untouched: each task's loss on the outputs, bit for bit."""
    tasks = [GESTURES, OrdinalProgress()]
    model = SegmentationModel(F, EncoderConfig(hidden=8), tasks, 0)
    x = _inputs()
    rng = np.random.default_rng(0)
    targets = [tf.constant(t.encode(rng.integers(0, t.num_classes, size=(2, T)))) for t in tasks]
    seeds = tf.constant(np.arange(2 * model.dropout_calls).reshape(-1, 2), tf.int64)
    out = model.apply(model.params(), x, _no_resets(x), seeds)
    expected = tf.stack([t.loss(out[t.name], y) for t, y in zip(tasks, targets)])
    got = model.losses(model.params(), tasks, x, _no_resets(x), targets, seeds)
    np.testing.assert_array_equal(got.numpy(), expected.numpy())


def _trainer(tmp_path, kind):
    rng = np.random.default_rng(0)
    inputs = [rng.normal(size=(int(rng.integers(30, 50)), F)).astype(np.float32)
              for _ in range(6)]
    tasks = [GESTURES, ProgressClassification(["s0", "s1", "s2", "s3", "s4"])]
    labels = {"gesture": [(x[:, 0] > 0).astype(int) * 2 for x in inputs],
              "progress": [np.minimum(np.arange(len(x)) * 5 // len(x), 4) for x in inputs]}
    data = SequenceSet([f"s{i}" for i in range(6)], inputs, labels)
    model = SegmentationModel(F, _small(kind), tasks, 0)
    optim = OptimConfig(optimizer="adam", learning_rate=1e-3, clip_norm=0.0, unit="sweeps",
                        total=8, decay_start=8)
    return GradNormTrainer(model, tasks, optim, TrainConfig(batch_size=3, eval_points=(8,),
                                                            plots="none"),
                           data, data, tmp_path, {}, 5.0, log=lambda m: None,
                           gradnorm=GradNormConfig())


@pytest.mark.parametrize("kind", ["ed-tcn", "ms-tcn"])
@pytest.mark.slow
def test_gradnorm_on_a_tcn_uses_the_last_shared_layer(tmp_path, kind):
    trainer = _trainer(tmp_path, kind)
    model = trainer.model
    last = (model.encoder.decoder_layers[-1].trainable_variables if kind == "ed-tcn"
            else model.refinement.stages[-1].last_layer_variables())
    assert {id(v) for v in trainer.shared} == {id(v) for v in last}
    inputs, resets, targets, valid = trainer.batch(0)
    assert valid is not None and not valid.all()                 # a padded sweep
    norms = []
    for i, task in enumerate(trainer.tasks):                     # ||grad_W L_i||, one tape each
        with tf.GradientTape() as tape:
            loss = model.losses(model.params(), trainer.tasks, tf.constant(inputs),
                                tf.constant(resets), [tf.constant(y) for y in targets],
                                None, tf.constant(valid))[i]
        norms.append(float(tf.linalg.global_norm(tape.gradient(loss, trainer.shared))))
    for sweep in range(8):
        out = trainer.step(sweep, 1e-3)
        trainer.record(out)
        w = trainer.weights.numpy()
        assert np.all(w > 0) and w.sum() == pytest.approx(2.0, abs=1e-5)
    assert np.all(np.isfinite(out)) and np.all(np.array(norms) > 0)


def _numpy_steps(kind, grads, lr):
    w, a, m, v = 1.0, 0.0, 0.0, 0.0
    for t, g in enumerate(grads, start=1):
        if kind == "rmsprop":
            a = RMSPROP_RHO * a + (1 - RMSPROP_RHO) * g * g
            w -= lr * g / (np.sqrt(a) + RMSPROP_EPSILON)
        else:
            b1, b2 = ADAM_BETAS
            m, v = b1 * m + (1 - b1) * g, b2 * v + (1 - b2) * g * g
            w -= lr * (m / (1 - b1 ** t)) / (np.sqrt(v / (1 - b2 ** t)) + ADAM_EPSILON)
    return w


@pytest.mark.parametrize("kind", ["rmsprop", "adam"])
def test_optimisers_follow_their_references_formulas(kind):
    var = tf.Variable([1.0])
    optimizer = build_optimizer([var], OptimConfig(optimizer=kind, clip_norm=0.0))
    grads = [0.5, -2.0, 0.1]
    for g in grads:
        optimizer.apply([tf.constant([g])], [var], tf.constant(0.01))
    assert float(var[0]) == pytest.approx(_numpy_steps(kind, grads, 0.01), rel=1e-5)


def test_momentum_belongs_to_sgd():
    with pytest.raises(ValueError, match="momentum applies to sgd"):
        OptimConfig(optimizer="adam", momentum=0.9)


@pytest.mark.parametrize("kind", ["ed-tcn", "ms-tcn"])
def test_every_variant_builds_and_trains_one_sweep(tmp_path, kind):
    for name, variant in VARIANTS.items():
        tasks = variant.tasks()
        model = SegmentationModel(F, _small(kind), tasks, 0)
        x = _inputs()
        rng = np.random.default_rng(0)
        targets = [tf.constant(t.encode(rng.integers(0, t.num_classes, size=(2, T))))
                   for t in tasks]
        with tf.GradientTape() as tape:
            losses = model.losses(model.params(), tasks, x, _no_resets(x), targets)
            total = tf.reduce_sum(losses)
        grads = tape.gradient(total, tf.nest.flatten(model.params()))
        assert losses.shape == (len(tasks),) and all(g is not None for g in grads), name


@pytest.mark.parametrize("kind,config,epochs,lr,factor", [
    ("ed-tcn", EDTCNConfig(filters=(16, 24)), 25, 1e-3, 6),
    ("ed-tcn", EDTCNConfig(filters=(16, 24), kernel=15), 25, 1e-3, 10),    # Lea et al.'s 3 Hz
    ("ms-tcn", MSTCNConfig(stages=2, layers=6, filters=16), 12, 3e-3, 6)])
@pytest.mark.slow
def test_tcn_learns_above_chance_on_a_held_out_user(synth_dir, tmp_path, kind, config, epochs,
                                                    lr, factor):
    """Small models with their reference optimiser (a higher rate for MS-TCN's few sweeps);
    ED-TCN also at its reference's rate, one labelled frame in ``factor``."""
    variant = get_variant("APc")
    optim = replace(variant.optim(kind), total=epochs, decay_start=epochs, learning_rate=lr)
    data = DataConfig(str(synth_dir), preprocessing=PreprocessConfig(resample_factor=factor))
    run = RunConfig(data=data, test_user="C", encoder=config, optim=optim,
                    train=TrainConfig(batch_size=3, eval_points=(epochs,), plots="none"))
    result = train_variant(variant, "fixed", run, tmp_path / f"{kind}-{factor}", log=lambda m: None)
    _, test = load_dataset(run.data).louo_split("C")
    for task, field in (("gesture", "gestures"), ("progress", "progress")):
        chance = chance_accuracy([getattr(t, field) for t in test])
        assert result["mean"][task]["accuracy"] > chance + 20, (task, result["mean"][task])


@pytest.mark.parametrize("kind", ["ed-tcn", "ms-tcn"])
@pytest.mark.slow
def test_commands_train_predict_evaluate_and_export_a_tcn_run(synth_dir, tmp_path, monkeypatch,
                                                              kind, capsys):
    monkeypatch.setenv("JIGSAWS_DIR", str(synth_dir))
    out = tmp_path / "x"
    assert multitask_main(["--encoder", kind, "--variant", "APoc", "--weighting", "gradnorm",
                           "--sweeps", "1", "--batch-size", "8", "--test-user", "D",
                           "--no-plots",
                           "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["run"]["encoder"]["kind"] == kind
    assert config["run"]["optim"]["optimizer"] in ("adam", "rmsprop")
    run = load_run(out)
    assert run.config.encoder.kind == kind and not run.online
    trial = synth_dir / "kinematics" / "AllGestures" / "Suturing_D001.txt"
    assert predict_main([str(out), str(trial), "--out", str(tmp_path / "pred"), "--no-plots"]) == 0
    assert evaluate_main([str(out), "--out", str(tmp_path / "ev"), "--no-plots"]) == 0
    assert export_main([str(out), "--out", str(tmp_path / "ex")]) == 0
    evaluated = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    trained = json.loads((out / "metrics.json").read_text())
    assert evaluated["metrics"]["gesture"]["accuracy"] == pytest.approx(
        trained["mean"]["gesture"]["accuracy"])


@pytest.mark.slow
def test_an_inner_run_holds_out_the_outer_test_user(synth_dir, tmp_path, monkeypatch, capsys):
    """``--hold-out B --test-user C``: a validation run inside outer fold B's training users."""
    monkeypatch.setenv("JIGSAWS_DIR", str(synth_dir))
    out = tmp_path / "inner"
    assert multitask_main(["--encoder", "ed-tcn", "--variant", "A", "--epochs", "1",
                           "--test-user", "C", "--hold-out", "B", "--no-plots",
                           "--out", str(out)]) == 0
    assert json.loads((out / "config.json").read_text())["run"]["held_out_users"] == ["B"]
    assert load_run(out).config.held_out_users == ("B",)
    capsys.readouterr()
    for hold_out, words in (("Z", "unknown held-out user 'Z' (--hold-out)"),
                            ("C", "test user C is also held out")):
        bad = tmp_path / f"bad-{hold_out}"
        code = multitask_main(["--encoder", "ed-tcn", "--variant", "A", "--epochs", "1",
                               "--test-user", "C", "--hold-out", hold_out, "--out", str(bad)])
        err = capsys.readouterr().err.strip()
        assert code != 0 and words in err and len(err.splitlines()) == 1, err
        assert not bad.exists()


def test_lstm_options_are_refused_with_a_tcn(synth_dir, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("JIGSAWS_DIR", str(synth_dir))
    with pytest.raises(SystemExit) as exit_:
        multitask_main(["--encoder", "ed-tcn", "--hidden", "12", "--out", str(tmp_path / "r")])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "--hidden is an LSTM setting" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "r").exists()


def test_grid_specs_choose_an_encoder_and_refuse_lstm_settings():
    spec = spec_from_dict({"encoder": "ms-tcn", "preset": "paper",
                           "experiments": [{"variants": ["A"]}]})
    assert spec.encoder == "ms-tcn"
    with pytest.raises(ValueError, match="hidden is an LSTM setting"):
        spec_from_dict({"encoder": "ed-tcn", "hidden": 64}, source="s.toml")
    with pytest.raises(ValueError, match="encoder must be one of"):
        spec_from_dict({"encoder": "tcn"})


def test_a_tcn_grids_epochs_set_its_reference_schedules_length():
    """``epochs`` with a TCN: its reference's optimiser and constant rate for that many epochs,
    evaluated at the same fractions of the length (the convergence ladders); without it, the
    reference's own length."""
    from multitask.grid.spec import schedule_epochs
    from rnn_seg.encoders.config import SCHEDULES

    key = RunKey("revised", "bidirectional", "APoc", "gradnorm", 0, "B")
    for encoder, reference in SCHEDULES.items():
        spec = spec_from_dict({"encoder": encoder, "preset": "paper", "epochs": 3 * 50})
        optim = run_config(spec, key).optim
        assert (optim.total, optim.decay_start) == (150, 150)
        assert (optim.optimizer, optim.learning_rate) == (reference.optim.optimizer,
                                                          reference.optim.learning_rate)
        assert schedule_epochs(spec, key) == 150
        unset = spec_from_dict({"encoder": encoder, "preset": "paper"})
        assert schedule_epochs(unset, key) == reference.optim.total
        for epochs in (150, 600):
            spec = spec_from_dict({"encoder": encoder, "preset": "paper", "epochs": epochs})
            train = run_config(spec, key).train
            assert train.batch_size == reference.batch_size
            assert len(train.eval_points) == 3 and train.eval_points[-1] == epochs
            for point, fraction in zip(train.eval_points, (100 / 120, 110 / 120, 1)):
                assert abs(point - fraction * epochs) <= 0.5
        for name, value in (("hidden", 64), ("schedule_factors", {"A": 2}),
                            ("precision", "mixed"), ("loops", 2)):
            with pytest.raises(ValueError, match=f"{name} is an LSTM setting"):
                spec_from_dict({"encoder": encoder, "epochs": 600, name: value}, source="s.toml")
        for epochs in (0, -3, 1.5, "600", True):
            with pytest.raises(ValueError, match=r"s.toml: epochs must be an integer >= 1"):
                spec_from_dict({"encoder": encoder, "epochs": epochs}, source="s.toml")


def test_grid_specs_set_the_sample_rate_and_ed_tcns_kernel(synth_dir):
    """Lea et al.'s released JIGSAWS ED-TCN: 3 Hz (one labelled frame in 10), 15-sample
    kernels; a spec without the keys compares equal to a grid.json written before them."""
    spec = spec_from_dict({"encoder": "ed-tcn", "data_dir": str(synth_dir),
                           "resample_factor": 10, "kernel": 15})
    config = run_config(spec, RunKey("original", "bidirectional", "A", "fixed", 0, "B"))
    assert config.encoder.kernel == 15 and config.encoder.filters == (64, 96)
    assert config.data.preprocessing.sample_hz == 3.0
    plain = spec_from_dict({"encoder": "ed-tcn", "data_dir": str(synth_dir)})
    default = run_config(plain, RunKey("original", "bidirectional", "A", "fixed", 0, "B"))
    assert default.encoder.kernel == 10 and default.data.preprocessing.sample_hz == 5.0
    older = {k: v for k, v in spec_payload(plain).items() if k not in ("kernel", "resample_factor")}
    assert comparable_spec(older) == comparable_spec(spec_payload(plain))
    assert comparable_spec(spec_payload(spec)) != comparable_spec(spec_payload(plain))
    for encoder in ("ms-tcn", "lstm"):
        with pytest.raises(ValueError, match=f"kernel is ED-TCN's setting .encoder is '{encoder}'"):
            spec_from_dict({"encoder": encoder, "kernel": 15})
    for key in ("kernel", "resample_factor"):
        with pytest.raises(ValueError, match=f"{key}"):
            spec_from_dict({"encoder": "ed-tcn", key: 0}, source="s.toml")


def test_a_config_without_encoder_kind_is_an_lstm():
    from rnn_seg.runs.folder import from_jsonable, to_jsonable
    lstm = to_jsonable(EncoderConfig())
    assert "kind" not in lstm                              # old records and hashes unchanged
    assert from_jsonable(EncoderConfig, lstm).kind == "lstm"
    for config in (MSTCNConfig(), EDTCNConfig(causal=True)):
        tcn = to_jsonable(RunConfig(DataConfig("d"), encoder=config))
        assert from_jsonable(RunConfig, tcn).encoder == config
    tcn["encoder"]["kind"] = "tcn"
    with pytest.raises(ValueError, match="run.encoder.kind: expected one of"):
        from_jsonable(RunConfig, tcn, "run")


def _lone_or_stacked(folder, seed, config):
    rng = np.random.default_rng(seed)
    inputs = [rng.normal(size=(int(rng.integers(20, 40)), F)).astype(np.float32)
              for _ in range(6)]
    data = SequenceSet([f"s{i}" for i in range(6)], inputs,
                       {"gesture": [(x[:, 0] > 0).astype(int) for x in inputs]})
    optim = OptimConfig(optimizer="adam", learning_rate=1e-2, clip_norm=0.0, unit="sweeps",
                        total=4, decay_start=4)
    return Trainer(SegmentationModel(F, config, [GESTURES], seed), [GESTURES], optim,
                   TrainConfig(batch_size=3, eval_points=(4,), plots="none", seed=seed), data,
                   data, folder, {}, 5.0, log=lambda m: None)


@pytest.mark.parametrize("kind", ["ed-tcn", "ms-tcn"])
@pytest.mark.slow
def test_a_tcn_trains_in_a_stack_as_alone(tmp_path, kind):
    """Members' sweeps padded to the longest (``rnn_seg.stack``), dropout included. MS-TCN with
    two stages of two layers: vectorising the step costs seconds a layer to trace."""
    config = _small(kind) if kind == "ed-tcn" else MSTCNConfig(stages=2, layers=2, filters=8)
    lone = [_lone_or_stacked(tmp_path / f"lone{s}", s, config) for s in (0, 1)]
    for trainer in lone:
        trainer.run()
    stacked = [_lone_or_stacked(tmp_path / f"stack{s}", s, config) for s in (0, 1)]
    TrainerStack(stacked).run()
    for a, b in zip(lone, stacked):
        for x, y in zip(a.variables, b.variables):
            np.testing.assert_allclose(y.numpy(), x.numpy(), atol=2e-5)
