"""Configurations survive config.json: ``from_jsonable`` inverts ``to_jsonable``, strictly."""
import json
from dataclasses import dataclass, field, fields, replace

import pytest

from baseline.config import RunConfig
from jigsaws_tools.dataset import DataConfig
from jigsaws_tools.preprocessing import PreprocessConfig
from jigsaws_tools.recording_format import JIGSAWS_FORMAT
from rnn_seg.lstm import EncoderConfig
from rnn_seg.optim import OptimConfig
from rnn_seg.runs.folder import ConfigError, from_jsonable, to_jsonable
from rnn_seg.trainer import TrainConfig


def _run_config() -> RunConfig:
    """Every nested dataclass with values off their defaults."""
    return RunConfig(
        data=DataConfig("/data/Suturing", feature_set="psm_all", annotations="original",
                        preprocessing=PreprocessConfig(cutoff_hz=2.0, resample_factor=3)),
        test_user="C",
        encoder=EncoderConfig(hidden=16, layers=2, bidirectional=False, reset_mode="corrected"),
        optim=OptimConfig(learning_rate=0.1, momentum=0.9, unit="sweeps", total=50, decay_start=20),
        train=TrainConfig(batch_size=3, seed=7, eval_points=(40, 50), prediction="per_sequence"))


def _saved(config) -> dict:
    return json.loads(json.dumps(to_jsonable(config)))


def test_round_trip_of_a_run_configuration():
    config = _run_config()
    assert from_jsonable(RunConfig, _saved(config)) == config


def test_fields_added_later_with_defaults_may_be_absent():
    saved = _saved(_run_config())
    del saved["train"]["plots"], saved["encoder"]
    rebuilt = from_jsonable(RunConfig, saved)
    assert rebuilt.train.plots is TrainConfig.plots and rebuilt.encoder == EncoderConfig()


@pytest.mark.parametrize("edit, where, words", [
    (lambda s: s["encoder"].update(hiden=8), "run.encoder", "unknown field 'hiden'"),
    (lambda s: s["encoder"].update(hidden="16"), "run.encoder.hidden", "expected int"),
    (lambda s: s["encoder"].update(hidden=16.0), "run.encoder.hidden", "expected int"),
    (lambda s: s["optim"].update(unit="hours"), "run.optim.unit", "expected one of"),
    (lambda s: s["train"].update(eval_points=[1, "x"]), "run.train.eval_points[1]", "expected int"),
    (lambda s: s.pop("data"), "run", "missing field 'data'"),
    (lambda s: s["data"].update(feature_set="nope"), "run.data", "unknown feature set"),
])
def test_a_bad_file_names_the_field_and_value(edit, where, words):
    saved = _saved(_run_config())
    edit(saved)
    with pytest.raises(ConfigError) as error:
        from_jsonable(RunConfig, saved, "config.json: run")
    assert str(error.value).startswith(f"config.json: {where}: ") and words in str(error.value)


@dataclass(frozen=True)
class _Optional:
    name: str | None = None
    weights: dict[str, float] = field(default_factory=dict)
    pair: tuple[int, str] = (0, "a")


def test_optional_mapping_and_fixed_tuple_fields():
    value = _Optional(name="x", weights={"a": 1.0, "b": 2.5}, pair=(3, "b"))
    assert from_jsonable(_Optional, _saved(value)) == value
    assert from_jsonable(_Optional, {"name": None, "weights": {"a": 1}}).weights == {"a": 1.0}
    with pytest.raises(ConfigError, match="expected 2 items"):
        from_jsonable(_Optional, {"pair": [1]})


def test_describe_prints_every_field_by_name_without_class_reprs():
    config = RunConfig(DataConfig("somewhere/Suturing"), test_user="D")
    text = config.describe()
    assert "Config(" not in text and "TaskDefinition(" not in text
    lines = dict(line.split(": ", 1) for line in text.splitlines())
    assert lines["test user"] == "D" and "task=Suturing" in lines["data"]
    for name in ("encoder", "optim", "train", "data.preprocessing"):
        owner = config.data if name.startswith("data.") else config
        part = getattr(owner, name.split(".")[-1])
        unrecorded = getattr(part, "unrecorded_defaults", ())    # left out at their default
        for f in fields(part):
            if f.name not in unrecorded:
                assert f"{f.name}=" in lines[name], (name, f.name)


def test_describe_summarises_long_sequences_that_config_json_records_in_full():
    """A format of the release's 76 columns by another name (a default format is not recorded)."""
    recording_format = replace(JIGSAWS_FORMAT, name="my_release")
    config = RunConfig(DataConfig("somewhere/Suturing", recording_format=recording_format),
                       train=TrainConfig(eval_points=tuple(range(10, 130, 10))))
    lines = dict(line.split(": ", 1) for line in config.describe().splitlines())
    assert lines["data.recording_format"] == (
        "name=my_release, rate_hz=30.0, delimiter=whitespace, header=False, "
        "columns=76 (mtml_pos_x ... psm2_gripper), time_column=, features=()")
    assert "eval_points=12 (10 ... 120)," in lines["train"]
    saved = _saved(config)
    assert saved["data"]["recording_format"]["columns"] == list(JIGSAWS_FORMAT.columns)
    assert saved["train"]["eval_points"] == list(range(10, 130, 10))


def test_held_out_users_are_recorded_only_when_given():
    """An inner (validation) run of an outer fold: recorded and restored; a plain run's record
    has no such key, so earlier settings hashes stay."""
    inner = replace(_run_config(), held_out_users=("B",))
    assert _saved(inner)["held_out_users"] == ["B"]
    assert from_jsonable(RunConfig, _saved(inner)) == inner
    assert "held_out_users" not in _saved(_run_config())
    assert "(held out: B)" in inner.describe().splitlines()[0]
    with pytest.raises(ValueError, match="test user C is also held out"):
        replace(_run_config(), held_out_users=("C",))
    with pytest.raises(ValueError, match="held_out_users must be a list of user letters"):
        replace(_run_config(), held_out_users="B")
