"""The factor study of results/tcn/PLAN_factors.md: inner runs in a grid, the factors' spec keys,
ED-TCN's Lea et al. options, and ``multitask-tables factors``."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tensorflow as tf

from multitask.evidence.cli import main as tables_main
from multitask.evidence.plans.factors import (BASELINE, PENDING, Level, _changes, choice,
                                              combination_spec, effects, fold_settings_toml,
                                              per_fold, settings)
from multitask.grid.cli import main as grid_main
from multitask.grid.folder import comparable_spec
from multitask.grid.spec import (RunKey, expand, fold_users, inner_fold, load_spec, run_arguments,
                                 run_config, spec_from_dict, spec_payload, validation_users,
                                 with_overrides)
from multitask.models.fold_run import variant_trainer
from multitask.models.run_record import variant_configs
from rnn_seg.encoders.config import EDTCNConfig
from rnn_seg.model import SegmentationModel
from rnn_seg.runs.folder import to_jsonable
from rnn_seg.runs.settings import settings_hash
from rnn_seg.tasks import SoftmaxClassification

ROOT = Path(__file__).resolve().parents[1]
USERS = tuple("BCDEFGHI")
GESTURES = SoftmaxClassification("gesture", list("abcd"))
FEATURES = 3


def _inner_spec(synth_dir, **keys):
    return spec_from_dict({"encoder": "ed-tcn", "data_dir": str(synth_dir), "seeds": [0],
                           "inner_validation": 2,
                           "experiments": [{"variants": ["A"], "annotations": ["original"]}],
                           **keys})


@pytest.mark.parametrize("encoder, epochs", [("ed-tcn", 200), ("ms-tcn", 50)])
def test_the_committed_tcn_specs_keep_their_config_and_settings_hash(encoder, epochs):
    """The new options hold their defaults unrecorded: a run of results/tcn/<encoder>.toml
    records what the committed run recorded, and hashes alike; so does the spec with ``epochs``
    at its reference's length (a ladder's shortest rung is the committed run)."""
    run = ROOT / f"results/tcn/{encoder}/runs/original/bidirectional/A-fixed/seed0/B/config.json"
    recorded = json.loads(run.read_text())
    committed = with_overrides(load_spec(ROOT / f"results/tcn/{encoder}.toml"),
                               data_dir="/elsewhere")
    assert committed.epochs is None
    for spec in (committed, with_overrides(committed, epochs=epochs)):
        configs = variant_configs(**run_arguments(spec, RunKey("original", "bidirectional", "A",
                                                               "fixed", 0, "B")),
                                  fingerprint=recorded["data_fingerprint"])
        assert settings_hash(configs) == recorded["settings_hash"]
        assert to_jsonable(configs["run"])["encoder"] == recorded["run"]["encoder"]
        assert "held_out_users" not in to_jsonable(configs["run"])


def test_inner_runs_follow_their_outer_fold_cyclically():
    assert validation_users(USERS, "B", 2) == ("C", "D")
    assert validation_users(USERS, "H", 2) == ("I", "B")
    assert validation_users(USERS, "I", 2) == ("B", "C")
    assert fold_users(inner_fold("H", "B")) == ("B", ("H",))
    assert fold_users("H") == ("H", ())
    with pytest.raises(ValueError, match="leaves no training user"):
        validation_users(USERS, "B", 7)


def test_an_inner_grid_holds_out_each_outer_user_from_training_and_scoring(synth_dir, tmp_path):
    """16 runs, none an outer fold's; each scored on its validation user only, its outer fold's
    user in neither its training nor its scored set, recorded in its config.json."""
    spec = _inner_spec(synth_dir)
    keys = expand(spec, USERS)
    assert len(keys) == 16 and {k.fold for k in keys} == {
        inner_fold(u, v) for u in USERS for v in validation_users(USERS, u, 2)}
    assert not {k.fold for k in keys} & set(USERS)
    assert all(k.path().name == k.fold for k in keys)
    key = next(k for k in keys if k.fold == "H-val-B")
    config = run_config(spec, key)
    assert (config.test_user, config.held_out_users) == ("B", ("H",))
    assert to_jsonable(config)["held_out_users"] == ["H"]
    trainer = variant_trainer(**run_arguments(spec, key), run_dir=tmp_path / "run",
                              log=lambda message: None)
    users = lambda names: {name.rsplit("_", 1)[-1][0] for name in names}  # noqa: E731
    assert users(trainer.test.names) == {"B"}
    assert "H" not in users(trainer.train.names) | users(trainer.test.names)
    assert users(trainer.train.names) == set(USERS) - {"B", "H"}


def test_the_factors_keys_reach_the_run_and_are_checked(synth_dir):
    spec = _inner_spec(synth_dir, lowpass=False, normalise=False, feature_set="all",
                       padding="reference", head_init="glorot", resample_factor=10, kernel=15)
    config = run_config(spec, expand(spec, USERS)[0])
    preprocessing = config.data.preprocessing
    assert (preprocessing.lowpass, preprocessing.normalise, preprocessing.resample_factor) == (
        False, False, 10)
    assert config.data.feature_set == "all" and len(config.data.features) == 76
    assert (config.encoder.padding, config.encoder.head_init, config.encoder.kernel) == (
        "reference", "glorot", 15)
    plain = _inner_spec(synth_dir)
    older = {k: v for k, v in spec_payload(plain).items()
             if k not in ("lowpass", "normalise", "feature_set", "padding", "head_init")}
    assert comparable_spec(older) == comparable_spec(spec_payload(plain))
    for keys, words in (({"padding": "reference", "encoder": "ms-tcn"}, "padding is ED-TCN's"),
                        ({"head_init": "glorot", "encoder": "lstm"}, "head_init is ED-TCN's"),
                        ({"padding": "zeros"}, "padding"), ({"feature_set": "some"},
                                                            "feature_set"),
                        ({"lowpass": "no"}, "lowpass must be true or false"),
                        ({"inner_validation": 0}, "inner_validation")):
        raw = {"encoder": "ed-tcn", **keys}
        with pytest.raises(ValueError, match=words):
            spec_from_dict(raw, source="s.toml")


def _model(config: EDTCNConfig, seed=0) -> SegmentationModel:
    return SegmentationModel(FEATURES, config, [GESTURES], seed)


def _inputs(steps, seed=1):
    return tf.constant(np.random.default_rng(seed).normal(size=(1, steps, FEATURES)), tf.float32)


def _run(model, x, valid=None):
    resets = tf.zeros(tf.shape(x)[:2], tf.bool)
    return model.apply(model.params(), x, resets, None, valid)["gesture"].numpy()


def test_reference_padding_fills_minus_one_unmasked_whatever_the_row_length():
    """Lea et al.'s padding: a real step's output does not depend on how far its row is padded
    (junk after the end reads as -1), the last steps read the -1 (the masked padding's do
    not), and it equals the sequence followed by enough -1 steps."""
    config = EDTCNConfig(filters=(8, 12), kernel=5, padding="reference")
    model = _model(config)
    x = _inputs(30)
    alone = _run(model, x)
    longer = tf.concat([x, tf.ones([1, 13, FEATURES]) * 7.0], axis=1)
    padded = _run(model, longer, tf.constant(np.arange(43)[None] < 30))
    np.testing.assert_allclose(padded[:, :30], alone, atol=1e-5)
    reach = model.encoder.reference_reach
    minus_one = tf.concat([x, -tf.ones([1, 2 * reach, FEATURES])], axis=1)
    np.testing.assert_allclose(_run(model, minus_one)[:, :30], alone, atol=1e-5)
    masked = _model(EDTCNConfig(filters=(8, 12), kernel=5))
    assert np.abs(_run(masked, x)[0, -1] - alone[0, -1]).max() > 1e-4     # same weights
    assert np.abs(_run(masked, x)[0, 0] - alone[0, 0]).max() < 1e-5       # far from the end


def test_glorot_heads_start_with_zero_bias_and_glorots_bound():
    default = _model(EDTCNConfig(filters=(8, 12), kernel=5)).heads["gesture"]
    glorot = _model(EDTCNConfig(filters=(8, 12), kernel=5, head_init="glorot")).heads["gesture"]
    assert np.all(glorot.b.numpy() == 0) and np.any(default.b.numpy() != 0)
    bound = (6 / (8 + 4)) ** 0.5
    assert np.abs(glorot.W.numpy()).max() <= bound < np.abs(glorot.W.numpy()).max() * 1.5
    assert np.abs(default.W.numpy()).max() <= 8 ** -0.5
    assert "head_init" not in to_jsonable(EDTCNConfig())
    assert to_jsonable(EDTCNConfig(head_init="glorot"))["head_init"] == "glorot"


def _level(name, changes, means, runs=None):
    """A level whose validation score on fold u is ``means[u]`` on every metric, from one run
    per fold (``u-val-x``), or from ``runs`` (run folder -> score) when given."""
    runs = runs or {f"{u}-val-x": score for u, score in means.items()}
    table = pd.DataFrame({"fold": list(runs), "outer": [f.split("-")[0] for f in runs],
                          **{m: list(runs.values())
                             for m in ("gesture_accuracy", "gesture_edit", "gesture_f1@10",
                                       "mean")}})
    return Level(name, None, changes, table)


def test_a_level_with_fewer_validation_users_is_compared_on_its_own():
    """A level holding only the first validation user of each fold (a pilot of the schedule
    ladder, say) is set against the baseline's runs of that user, not the baseline's mean
    over both."""
    base = _level(BASELINE, {}, {"B": 85.0}, runs={"B-val-C": 80.0, "B-val-D": 90.0})
    longer = _level("S-600", {"epochs": 600}, {"B": 83.0}, runs={"B-val-C": 83.0})
    assert longer.factors == ("S",)
    assert effects(base, [longer]).at[0, "edit_diff"] == pytest.approx(3.0)
    row = per_fold(base, [longer]).set_index("metric").loc["edit"]
    assert (row.baseline_score, row.difference) == (pytest.approx(80.0), pytest.approx(3.0))
    both = _level("L-off", {"lowpass": False}, {"B": 86.0},
                  runs={"B-val-C": 81.0, "B-val-D": 91.0})
    assert effects(base, [both]).at[0, "edit_diff"] == pytest.approx(1.0)
    better = _level("S-300", {"epochs": 300}, {"B": 95.0}, runs={"B-val-C": 95.0})
    assert choice(base, [better]).empty       # a schedule is no fold's setting (fold_settings)


def test_a_level_with_more_validation_users_than_the_baseline_is_refused():
    baseline = load_spec(ROOT / "results/tcn/factors/baseline.toml")
    more = with_overrides(baseline, inner_validation=3)
    with pytest.raises(ValueError, match=r"level: inner_validation 3 is more than the "
                                         r"baseline's 2"):
        _changes(Path("level"), more, baseline)
    fewer = with_overrides(baseline, inner_validation=1, epochs=600)
    assert _changes(Path("level"), fewer, baseline) == {"epochs": 600}


def test_each_fold_takes_per_factor_its_best_eligible_level_and_combines_them():
    base = _level(BASELINE, {}, {"B": 80.0, "C": 80.0, "D": 80.0})
    k15 = _level("T-5hz-k15", {"kernel": 15}, {"B": 81.5, "C": 80.5, "D": 82.0})
    k20 = _level("T-5hz-k20", {"kernel": 20}, {"B": 82.0, "C": 80.0, "D": 81.0})
    slow = _level("T-3hz-k15", {"resample_factor": 10, "kernel": 15},
                  {"B": 90.0, "C": 90.0, "D": 90.0})
    lowpass = _level("L-off", {"lowpass": False}, {"B": 81.0, "C": 79.0, "D": 80.9})
    singles = [k15, k20, slow, lowpass]
    chosen = choice(base, singles)
    taken = {(r.fold, r.factor): r.taken for r in chosen.itertuples()}
    assert taken == {("B", "T"): "T-5hz-k20", ("B", "L"): "L-off", ("C", "T"): BASELINE,
                     ("C", "L"): BASELINE, ("D", "T"): "T-5hz-k15", ("D", "L"): BASELINE}
    assert "T-3hz-k15" not in " ".join(chosen.levels)          # 3 Hz: not the paper's rate
    first = settings(base, singles, [], chosen).set_index("fold")
    assert list(first.setting) == [PENDING, BASELINE, "T-5hz-k15"]
    assert first.at["B", "combination"] == "T-5hz-k20 + L-off"
    assert first.other_rate_best.tolist() == ["T-3hz-k15"] * 3 and first.other_rate_eligible.all()
    ran = _level("combination-B", {"kernel": 20, "lowpass": False}, {"B": 81.2})
    second = settings(base, singles, [ran], chosen).set_index("fold")
    assert second.at["B", "setting"] == "T-5hz-k20"               # 1.2 < 2.0 - 0.5
    better = _level("combination-B", {"kernel": 20, "lowpass": False}, {"B": 81.6})
    assert settings(base, singles, [better], chosen).set_index("fold").at[
        "B", "setting"] == "T-5hz-k20 + L-off"


def test_a_combination_spec_is_the_baselines_with_the_levels_keys(tmp_path):
    baseline = load_spec(ROOT / "results/tcn/factors/baseline.toml")
    levels = [_level("T-5hz-k20", {"kernel": 20}, {}), _level("L-off", {"lowpass": False}, {})]
    path = tmp_path / "combination-B-D.toml"
    path.write_text(combination_spec(baseline, levels, ("B", "D")))
    spec = load_spec(path)
    assert (spec.kernel, spec.lowpass, spec.test_users) == (20, False, ("B", "D"))
    assert comparable_spec(spec_payload(spec)) == comparable_spec(spec_payload(
        with_overrides(baseline, kernel=20, lowpass=False, test_users=("B", "D"))))


def test_the_settled_settings_become_a_specs_fold_settings(tmp_path):
    """fold_settings.toml, added to the baseline's spec, trains each fold at its setting (a
    combination's keys merged, a baseline fold at the spec's own)."""
    singles = [_level("T-5hz-k25", {"kernel": 25}, {}), _level("L-off", {"lowpass": False}, {}),
               _level("T-5hz-k15", {"kernel": 15}, {})]
    chosen = pd.DataFrame({"fold": ["B", "C", "D"],
                           "setting": ["T-5hz-k25 + L-off", BASELINE, "T-5hz-k15"]})
    path = tmp_path / "spec.toml"
    path.write_text((ROOT / "results/tcn/factors/baseline.toml").read_text()
                    + fold_settings_toml(chosen, singles))
    spec = with_overrides(load_spec(path), data_dir="/elsewhere")
    assert spec.fold_settings == {"B": {"kernel": 25, "lowpass": False}, "D": {"kernel": 15}}
    key = expand(spec, USERS)[0]
    config = run_config(spec, RunKey(key.annotations, key.direction, key.variant, key.weighting,
                                     0, "C"))
    assert (config.encoder.kernel, config.data.preprocessing.lowpass) == (10, True)


def test_the_committed_factor_specs_are_the_plans_levels():
    """One spec per level of section C, each the baseline's but its level's keys; 16 inner
    runs each, 224 in all."""
    folder = ROOT / "results/tcn/factors"
    specs = {path.stem: load_spec(path) for path in sorted(folder.glob("*.toml"))}
    baseline = spec_payload(specs.pop("baseline"))
    changed = {name: {k: v for k, v in spec_payload(spec).items() if baseline[k] != v}
               for name, spec in specs.items()}
    assert changed == {
        "T-5hz-k15": {"kernel": 15}, "T-5hz-k20": {"kernel": 20}, "T-5hz-k25": {"kernel": 25},
        "T-3hz-k15": {"resample_factor": 10, "kernel": 15},
        "T-3hz-k6": {"resample_factor": 10, "kernel": 6},
        "T-6hz-k15": {"resample_factor": 5, "kernel": 15},
        "T-10hz-k20": {"resample_factor": 3, "kernel": 20},
        "L-off": {"lowpass": False}, "N-off": {"normalise": False},
        "F-psm_all": {"feature_set": "psm_all"}, "F-all": {"feature_set": "all"},
        "P-reference": {"padding": "reference"}, "H-glorot": {"head_init": "glorot"}}
    spec = load_spec(folder / "baseline.toml")
    config = run_config(with_overrides(spec, data_dir="/elsewhere"),
                        expand(spec, USERS)[0])
    assert (config.optim.optimizer, config.optim.learning_rate, config.optim.total) == (
        "rmsprop", 1e-3, 200)
    assert config.train.eval_points == (167, 183, 200) and config.train.batch_size == 8
    assert sum(len(expand(s, USERS)) for s in [spec, *specs.values()]) == 224


TINY = """
preset = "quick"
encoder = "ed-tcn"
data_dir = "{data}"
test_users = ["B"]
inner_validation = 1
epochs = 3
plots = "none"
{level}
[[experiments]]
variants = ["A"]
annotations = ["original"]
"""


@pytest.fixture(scope="module")
def inner_grids(tmp_path_factory, synth_dir) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("factors")
    grids = {}
    for name, level in (("baseline", ""), ("T-5hz-k5", "kernel = 5")):
        spec = root / f"{name}.toml"
        spec.write_text(TINY.format(data=synth_dir, level=level))
        assert grid_main(["--spec", str(spec), "--out", str(root / name), "--workers", "0"]) == 0
        grids[name] = root / name
    return grids


@pytest.mark.slow
def test_factor_tables_from_inner_grids_and_no_other_table_of_them(inner_grids, tmp_path,
                                                                   capsys):
    out = tmp_path / "tables"
    assert tables_main(["factors", str(inner_grids["baseline"]), str(inner_grids["T-5hz-k5"]),
                        "--out", str(out)]) == 0
    effects = pd.read_csv(out / "factors.csv")
    assert effects.level.tolist() == ["T-5hz-k5"] and effects.factors.tolist() == ["T"]
    per_fold = pd.read_csv(out / "factors_per_fold.csv")
    assert set(per_fold.fold) == {"B"} and len(per_fold) == 4
    row = per_fold.set_index("metric").loc["mean"]
    assert row.difference == pytest.approx(row.level_score - row.baseline_score, abs=2e-4)
    assert json.loads((out / "factors.json").read_text())
    archives = {name: tmp_path / "archives" / name for name in inner_grids}
    for name, archive in archives.items():           # no time-only scores of any outer user
        assert tables_main(["archive", str(inner_grids[name]), str(archive)]) == 0
        assert "time_only" not in json.loads((archive / "archive.json").read_text()) or not \
            json.loads((archive / "archive.json").read_text())["time_only"]
    assert tables_main(["factors", str(archives["baseline"]), str(archives["T-5hz-k5"]),
                        "--out", str(tmp_path / "from-archives")]) == 0
    assert (tmp_path / "from-archives/factors.csv").read_bytes() == (
        out / "factors.csv").read_bytes()
    capsys.readouterr()
    assert tables_main(["paper", str(inner_grids["baseline"]), "--out",
                        str(tmp_path / "paper")]) != 0
    err = capsys.readouterr().err
    assert "inner runs" in err and "multitask-tables factors" in err
    assert not (tmp_path / "paper").exists()
    assert tables_main(["factors", str(inner_grids["T-5hz-k5"]), str(inner_grids["baseline"]),
                        str(inner_grids["baseline"]), "--out", str(tmp_path / "t2")]) != 0

