"""A user's own encoder (issue #63, docs/YOUR_METHOD.md): ``examples/gru_encoder.py`` named by its
import path trains through the project's heads on the synthetic release, learns, evaluates,
predicts and exports; its source is recorded by hash and a changed source is refused; a grid of
it runs and tabulates beside a built-in encoder's; bad encoders are one-line errors (exit 2).
A grid spec also takes a recording format: the LOUO grid on recordings of another rate and
column layout."""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jigsaws_tools.release import discover
from multitask.evidence.cli import main as tables_main
from multitask.evidence.runs.pooling import MixedSettings, pool
from multitask.grid.cli import main as grid_main
from multitask.grid.spec import spec_from_dict
from multitask.inference.evaluate_cli import main as evaluate_main
from multitask.inference.export_cli import main as export_main
from multitask.inference.predict_cli import main as predict_main
from multitask.models.run_record import read_run_record
from multitask.train_cli import main as train_main
from tests.robot_recordings import RATE, write_robot_folder
from tests.test_grid import TINY

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
GRU = "gru_encoder:build"
#: The synthetic release's gestures: 10, so chance accuracy is at most the commonest one's share.
CHANCE_MARGIN = 20.0


@pytest.fixture(scope="module")
def importable(tmp_path_factory):
    """``examples/`` and a folder of the test's own encoders on ``sys.path`` and ``PYTHONPATH``
    (the grid's workers), as a user puts their module's folder."""
    own = tmp_path_factory.mktemp("encoders")
    saved_path, saved_env = list(sys.path), os.environ.get("PYTHONPATH")
    folders = [str(EXAMPLES), str(own)]
    sys.path[:0] = folders
    os.environ["PYTHONPATH"] = os.pathsep.join(folders + ([saved_env] if saved_env else []))
    yield own
    sys.path[:] = saved_path
    if saved_env is None:
        os.environ.pop("PYTHONPATH", None)
    else:
        os.environ["PYTHONPATH"] = saved_env


def _train(data, out, encoder, *extra) -> int:
    return train_main(["--data-dir", str(data), "--encoder", encoder, "--variant", "APc",
                       "--test-user", "B", "--no-plots", "--threads", "1", "--out", str(out),
                       *extra])


@pytest.fixture(scope="module")
def gru_run(importable, synth_dir, tmp_path_factory):
    """The example encoder, copied under a module name of the test's own (so that its source
    can be changed), trained 6 epochs on fold B (held-out gesture accuracy 94 % against a
    commonest-gesture share of 27 % when this was written; 96 % after 12 epochs)."""
    shutil.copy(EXAMPLES / "gru_encoder.py", importable / "my_gru.py")
    out = tmp_path_factory.mktemp("gru") / "run"
    assert _train(synth_dir, out, "my_gru:build", "--epochs", "6") == 0
    return out


def _error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


@pytest.mark.slow
def test_it_learns_on_held_out_data_and_records_path_and_hash(gru_run, synth_dir):
    metrics = json.loads((gru_run / "metrics.json").read_text())["mean"]
    labels = np.concatenate([pd.read_csv(p)["gesture_true"].to_numpy() for p in
                             sorted((gru_run / "eval").glob("*/predictions/*.csv"))])
    chance = 100 * np.bincount(pd.factorize(labels)[0]).max() / len(labels)
    assert metrics["gesture"]["accuracy"] > chance + CHANCE_MARGIN, (metrics, chance)
    encoder = json.loads((gru_run / "config.json").read_text())["run"]["encoder"]
    source = Path(sys.modules["my_gru"].__file__)
    assert encoder["kind"] == "custom" and encoder["path"] == "my_gru:build"
    assert encoder["source_sha256"] == hashlib.sha256(source.read_bytes()).hexdigest()
    assert read_run_record(gru_run).config.encoder.path == "my_gru:build"


@pytest.mark.slow
def test_it_evaluates_predicts_and_exports(gru_run, synth_dir, tmp_path):
    assert evaluate_main([str(gru_run)]) == 0
    trial = discover(synth_dir).trials[0].kinematics
    assert predict_main([str(gru_run), str(trial), "--out", str(tmp_path / "labels")]) == 0
    assert list((tmp_path / "labels").glob("*.csv"))
    assert export_main([str(gru_run), "--out", str(tmp_path / "exported")]) == 0
    assert (tmp_path / "exported" / "saved_model.pb").is_file()


@pytest.mark.slow
def test_a_changed_or_missing_source_is_refused_naming_the_path(gru_run, importable, tmp_path,
                                                              capsys):
    source = importable / "my_gru.py"
    original = source.read_text()
    try:
        source.write_text(original + "\n# changed\n")
        assert evaluate_main([str(gru_run)]) == 2
        err = _error(capsys)
        assert "my_gru:build" in err and "changed" in err, err
        source.unlink()
        assert evaluate_main([str(gru_run)]) == 2
        err = _error(capsys)
        assert "my_gru:build" in err and "no module my_gru" in err, err
    finally:
        source.write_text(original)
    assert evaluate_main([str(gru_run), "--overwrite"]) == 0       # the same source again


BAD = {
    "no_such_module_xyz:build": "no module no_such_module_xyz",
    "bad_encoders:missing": "has no name 'missing'",
    "bad_encoders:NUMBER": "NUMBER is of type int, not a function or class",
    "bad_encoders:wrong_shape": "not [2, 7, D]",
    "bad_encoders:shorter": "not [2, 7, D]",
    "bad_encoders:batch_norm": "non-trainable state",
}
BAD_MODULE = '''
import keras

NUMBER = 3


def wrong_shape(input_size, config):
    return keras.layers.Flatten()         # [B, T * F]: no time axis


def shorter(input_size, config):
    return keras.layers.MaxPooling1D(2)


def batch_norm(input_size, config):
    return keras.Sequential([keras.layers.Dense(8), keras.layers.BatchNormalization()])
'''


@pytest.mark.parametrize("path", list(BAD))
def test_a_bad_encoder_is_one_line_naming_it(path, importable, synth_dir, tmp_path, capsys):
    (importable / "bad_encoders.py").write_text(BAD_MODULE)
    out = tmp_path / "run"
    assert _train(synth_dir, out, path, "--epochs", "1") == 2
    err = _error(capsys)
    assert path in err and BAD[path] in err, err
    assert not (out / "config.json").exists()


def test_a_path_of_another_form_is_refused_by_the_parser(capsys, tmp_path):
    with pytest.raises(SystemExit) as stop:
        train_main(["--synthetic", "--encoder", "not a path:", "--out", str(tmp_path)])
    assert stop.value.code == 2 and "package.module:name" in capsys.readouterr().err


# --- a grid of it, beside a built-in encoder's -----------------------------------------------

SPEC = """
preset = "quick"
data_dir = "{data}"
test_users = ["B", "C"]
seeds = [0]
epochs = 2
plots = "none"
encoder = "{encoder}"
{extra}
[[experiments]]
variants = ["APc"]
"""


@pytest.fixture(scope="module")
def grids(importable, synth_dir, tmp_path_factory):
    root = tmp_path_factory.mktemp("encoder_grids")
    made = {}
    for name, encoder, extra in (("gru", GRU, ""), ("lstm", "lstm", "hidden = 16")):
        spec = root / f"{name}.toml"
        spec.write_text(SPEC.format(data=synth_dir, encoder=encoder, extra=extra))
        assert grid_main(["--spec", str(spec), "--out", str(root / name), "--workers", "1",
                          "--threads", "1"]) == 0
        made[name] = root / name
    return made


@pytest.mark.slow
def test_a_grid_of_it_tabulates_beside_a_built_in_encoder(grids, tmp_path):
    assert tables_main(["paper", str(grids["gru"]), "--out", str(tmp_path / "gru"),
                        "--no-figures"]) == 0
    assert (tmp_path / "gru" / "table1.csv").is_file()
    assert tables_main(["architectures", str(grids["lstm"]), str(grids["gru"]),
                        "--out", str(tmp_path / "side")]) == 0
    written = " ".join(p.read_text() for p in (tmp_path / "side").rglob("*")
                       if p.is_file() and p.suffix in (".csv", ".md"))
    assert GRU in written and "LSTM-16" in written


@pytest.mark.slow
def test_runs_of_two_sources_of_one_encoder_are_never_pooled(grids, tmp_path):
    runs = sorted(p.parent for p in grids["gru"].glob("runs/*/*/*/*/*/config.json"))
    records = {run: read_run_record(run) for run in runs}
    trained = records[runs[0]].config.encoder.source_sha256
    other = tmp_path / "other_source"
    shutil.copytree(runs[0], other)
    saved = json.loads((other / "config.json").read_text())
    saved["run"]["encoder"]["source_sha256"] = "0" * 64
    (other / "config.json").write_text(json.dumps(saved))
    records[other] = read_run_record(other)
    with pytest.raises(MixedSettings) as error:
        pool(records, "grids")
    assert f"{GRU} (sha256 000000000000)" in str(error.value)
    assert f"{GRU} (sha256 {trained[:12]})" in str(error.value)


def test_a_spec_refuses_the_lstm_s_settings_with_a_user_s_encoder():
    with pytest.raises(ValueError, match="hidden is an LSTM setting"):
        spec_from_dict({"encoder": GRU, "hidden": 8})
    with pytest.raises(ValueError, match="import path"):
        spec_from_dict({"encoder": "gru encoder:build"})


# --- a grid on a user's recordings: another rate and column layout ---------------------------

@pytest.mark.slow
def test_a_grid_runs_tabulates_and_pairs_on_recordings_of_another_format(synth_dir, tmp_path,
                                                                       capsys):
    robot = write_robot_folder(synth_dir, tmp_path / "robot")
    spec = tmp_path / "robot.toml"
    spec.write_text(f'format = "{robot / "my_robot.toml"}"\n' + TINY.format(data=robot / "data"))
    grid = tmp_path / "grid"
    assert grid_main(["--spec", str(spec), "--out", str(grid), "--workers", "1",
                      "--threads", "1"]) == 0
    configs = [json.loads(p.read_text()) for p in grid.glob("runs/*/*/*/*/*/config.json")]
    assert len(configs) == 4
    assert {c["run"]["data"]["recording_format"]["rate_hz"] for c in configs} == {float(RATE)}
    assert json.loads((grid / "grid.json").read_text())["spec"]["format"] == str(
        (robot / "my_robot.toml").resolve())
    assert tables_main(["paper", str(grid), "--out", str(tmp_path / "tables"),
                        "--no-figures"]) == 0
    assert (tmp_path / "tables" / "table1.csv").is_file()
    capsys.readouterr()
    assert tables_main(["pair", str(grid), "APc-fixed", "A-fixed", "--metric",
                        "gesture_edit"]) == 0
    assert "APc-fixed" in capsys.readouterr().out


def test_an_older_grid_record_without_format_reads_as_the_release_s():
    from multitask.grid.folder import comparable_spec
    from multitask.grid.spec import GridSpec, spec_payload

    older = {k: v for k, v in spec_payload(GridSpec()).items() if k != "format"}
    assert comparable_spec(older) == comparable_spec(spec_payload(GridSpec()))
    assert spec_from_dict(older).recording_format().is_default
