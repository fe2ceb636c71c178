"""A nested selection in one grid (``fold_settings``): settings chosen per outer fold on its
training users (results/tcn/PLAN_factors.md, section D.2) reach each fold's runs and inner runs,
are recorded by every run, and make one configuration that tables pool, compare with other
architectures on the same data, and refuse when a run does not hold its fold's settings."""
from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.runs.checks import other_settings
from multitask.evidence.runs.pooling import MixedSettings, pool
from multitask.grid.cli import main as grid_main
from multitask.grid.folder import GRID_RECORD
from multitask.grid.spec import (RunKey, expand, inner_fold, run_arguments, run_config,
                                 spec_from_dict, spec_payload)
from multitask.models.run_record import read_run_record, variant_configs
from rnn_seg.runs.folder import read_json, write_json
from rnn_seg.runs.settings import settings_of

USERS = tuple("BCDEFGHI")
SELECTION = {"B": {"kernel": 5, "lowpass": False}, "C": {"kernel": 7}}


def _spec(synth_dir, **keys):
    return spec_from_dict({"encoder": "ed-tcn", "data_dir": str(synth_dir), "seeds": [0],
                           "experiments": [{"variants": ["A"], "annotations": ["original"]}],
                           **keys})


def _key(fold: str, seed: int = 0) -> RunKey:
    return RunKey("original", "bidirectional", "A", "fixed", seed, fold)


def _write_records(root: Path, spec, keys) -> dict[Path, Path]:
    """The config.json of each run at ``keys`` as ``spec``'s grid writes it, without training;
    run path (relative to ``root``) -> its config.json."""
    written = {}
    for key in keys:
        write_json(root / key.path() / "config.json",
                   variant_configs(**run_arguments(spec, key)))
        written[key.path()] = root / key.path() / "config.json"
    return written


def test_each_outer_fold_and_its_inner_runs_train_with_its_own_settings(synth_dir):
    spec = _spec(synth_dir, fold_settings=SELECTION, inner_validation=1)
    for fold, (kernel, lowpass) in {"B": (5, False), "C": (7, True), "D": (10, True)}.items():
        for run in (fold, inner_fold(fold, USERS[USERS.index(fold) + 1])):
            config = run_config(spec, _key(run))
            assert (config.encoder.kernel, config.data.preprocessing.lowpass) == (kernel, lowpass)
    assert len(expand(spec, USERS)) == 8


def test_every_run_records_the_whole_selection(synth_dir):
    spec = _spec(synth_dir, fold_settings=SELECTION)
    records = {fold: variant_configs(**run_arguments(spec, _key(fold))) for fold in "BCD"}
    selections = {fold: record["selection"] for fold, record in records.items()}
    assert selections["B"] == selections["C"] == selections["D"]
    selection = selections["B"]
    names = {"run.encoder.kernel", "run.data.preprocessing.lowpass"}
    assert set(selection.common) == names
    assert selection.per_fold["B"] == {"run.encoder.kernel": 5,
                                       "run.data.preprocessing.lowpass": False}
    assert selection.common == {"run.encoder.kernel": 10, "run.data.preprocessing.lowpass": True}
    for fold, record in records.items():          # each run holds what its selection says
        settings = settings_of(record)
        assert {n: settings.get(n) for n in names} == selection.expected(fold)
    assert selection.common_fingerprint == records["D"]["data_fingerprint"]
    assert records["B"]["data_fingerprint"] != selection.common_fingerprint     # lowpass off
    assert "selection" not in variant_configs(**run_arguments(_spec(synth_dir), _key("B")))


@pytest.mark.parametrize("keys, words", [
    ({"fold_settings": {"B": {"hidden": 64}}}, "fold_settings.B: hidden cannot be set per fold"),
    ({"fold_settings": {"B": {"kernel": 0}}}, "fold_settings.B: kernel"),
    ({"fold_settings": {"B": {"kernel": 5}}, "encoder": "ms-tcn"},
     "fold_settings.B: kernel is ED-TCN's setting"),
    ({"fold_settings": {"B": {"lowpass": "no"}}}, "fold_settings.B: lowpass must be true or"),
    ({"fold_settings": {"B": 5}}, "fold_settings.B must be a table of settings"),
    ({"fold_settings": {}}, "fold_settings must be a table of outer folds"),
    ({"fold_settings": {"B": {"kernel": 5}, "C": {}}}, "fold_settings.C sets nothing"),
    ({"fold_settings": {"E": {"kernel": 5}}, "test_users": ["B", "C"]},
     "fold_settings.E: E is not among test_users"),
    ({"fold_settings": {1: {"kernel": 5}}}, "fold_settings must name outer folds by their user"),
    ({"fold_settings": {"B": {"feature_set": ["all"]}}},
     "fold_settings.B: feature_set must be one of"),
    ({"fold_settings": {"B": {"feature_set": {"all": 1}}}},
     "fold_settings.B: feature_set must be one of"),
])
def test_a_bad_selection_is_one_line_naming_the_fold_and_key(keys, words):
    with pytest.raises(ValueError, match=words) as error:
        spec_from_dict({"encoder": "ed-tcn", **keys}, source="s.toml")
    assert str(error.value).startswith("s.toml: ") and "\n" not in str(error.value)


@pytest.mark.parametrize("keys, words", [
    ({"kernel": 0}, "kernel must be an integer >= 1"),
    ({"epochs": 0}, "epochs must be an integer >= 1"),
    ({"inner_validation": 0}, "inner_validation must be an integer >= 1"),
    ({"experiments": []}, "experiments must be a non-empty list"),
])
def test_a_bad_key_beside_a_selection_is_named_as_the_specs_not_a_folds(keys, words):
    with pytest.raises(ValueError, match=words) as error:
        spec_from_dict({"encoder": "ed-tcn", "fold_settings": {"B": {"lowpass": False}},
                        **keys}, source="s.toml")
    assert str(error.value).startswith(f"s.toml: {words}")


def test_a_selection_of_a_fold_the_release_lacks_is_refused(synth_dir, tmp_path, capsys):
    with pytest.raises(ValueError, match="fold_settings names fold.s. Z, not among"):
        expand(_spec(synth_dir, fold_settings={"Z": {"kernel": 5}}), USERS)
    spec = tmp_path / "s.toml"
    spec.write_text(TINY.format(encoder="ed-tcn", data=synth_dir, epochs=3, extra="").replace(
        'test_users = ["B", "C"]', "") + "[fold_settings.Z]\nkernel = 5\n")
    capsys.readouterr()
    assert grid_main(["--spec", str(spec), "--out", str(tmp_path / "g"), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert f"{spec}: fold_settings names fold(s) Z" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "g").exists()


def test_the_tables_check_an_inner_selection_grid_against_its_spec(synth_dir, tmp_path):
    """Inner runs (folders ``<u>-val-<v>``) of a selection over the release's users (no
    ``test_users``): each checked against the settings of its outer fold, as
    ``multitask-tables factors`` and ``ladder`` read them; a folder of another fold's settings
    is named."""
    spec = _spec(synth_dir, fold_settings=SELECTION, inner_validation=1)
    keys = expand(spec, USERS)
    written = _write_records(tmp_path, spec, keys)
    write_json(tmp_path / GRID_RECORD, {"spec": spec_payload(spec),
                                        "runs": [str(key.path()) for key in keys]})
    runs = {key.path(): key for key in keys}
    assert other_settings(tmp_path, runs) == {}
    moved = _key(inner_fold("B", "C")).path()
    saved = read_json(written[moved])
    saved["run"]["encoder"]["kernel"] = 10                  # fold D's (the spec's), not B's
    write_json(written[moved], saved)
    assert list(other_settings(tmp_path, runs)) == [moved]
    assert "run.encoder.kernel: 10 -> 5" in other_settings(tmp_path, runs)[moved]


@pytest.mark.parametrize("fold_settings, edited", [
    ({"B": {"kernel": 5}}, "B"),                 # fold B's data: the common setting's
    (SELECTION, "C"),                            # a fold at the common setting
    ({"B": {"lowpass": False}}, "B"),            # fold B's own data, its other seed's
])
def test_runs_of_a_selection_on_the_same_data_record_one_fingerprint(
        synth_dir, tmp_path, fold_settings, edited):
    """The data fingerprint hashes the data: two runs of one selection on the same data (a fold
    whose selected settings leave the data at the common setting counts as on the common
    setting's data) that record other fingerprints are refused, naming the run."""
    spec = _spec(synth_dir, fold_settings=fold_settings)
    keys = [_key(fold, seed) for fold in "BC" for seed in (0, 1)]
    written = _write_records(tmp_path, spec, keys)

    def records():
        return {path: read_run_record(tmp_path / path) for path in written}

    pool(records(), tmp_path)
    saved = read_json(written[_key(edited).path()])
    saved["data_fingerprint"] = "0" * 24
    write_json(written[_key(edited).path()], saved)
    with pytest.raises(MixedSettings, match="record other data fingerprints") as error:
        pool(records(), tmp_path)
    assert f"{'0' * 24} ({_key(edited).path()})" in str(error.value)
    assert "\n" not in str(error.value)


def test_two_configurations_of_a_selection_on_one_folds_data_record_one_fingerprint(
        synth_dir, tmp_path):
    """Runs of A and APc on fold B, whose selection changes its data (low-pass filter off):
    each configuration's runs agree, yet the two record other fingerprints for the same data,
    so their pairing would compare other data: refused."""
    spec = spec_from_dict({"encoder": "ed-tcn", "data_dir": str(synth_dir), "seeds": [0],
                           "experiments": [{"variants": ["A", "APc"],
                                            "annotations": ["original"]}],
                           "fold_settings": {"B": {"lowpass": False}}})
    keys = [replace(_key(fold), variant=variant) for variant in ("A", "APc") for fold in "BC"]
    written = _write_records(tmp_path, spec, keys)
    other = replace(_key("B"), variant="APc").path()
    saved = read_json(written[other])
    saved["data_fingerprint"] = "0" * 24
    write_json(written[other], saved)
    with pytest.raises(MixedSettings, match=f"{'0' * 24} [(]{other}[)]"):
        pool({path: read_run_record(tmp_path / path) for path in written}, tmp_path)


def test_a_run_without_its_selection_is_named_beside_the_runs_of_it(synth_dir, tmp_path):
    """A run whose config.json lost its selection differs from the selection's runs in the
    settings the selection chooses per fold, said as such (not as settings they lack)."""
    spec = _spec(synth_dir, fold_settings=SELECTION)
    written = _write_records(tmp_path, spec, [_key("B"), _key("D")])
    saved = read_json(written[_key("B").path()])
    del saved["selection"]
    write_json(written[_key("B").path()], saved)
    with pytest.raises(MixedSettings) as error:
        pool({path: read_run_record(tmp_path / path) for path in written}, tmp_path)
    assert (f"run.encoder.kernel 5 ({_key('B').path()}) / (chosen per fold) "
            f"({_key('D').path()})") in str(error.value)


def test_values_that_read_alike_are_told_apart_in_a_refusal(synth_dir, tmp_path):
    """A selection's kernel of fold B written as "5" in one run's config.json, 5 in the
    other's: the refusal shows both, not an empty list of differences."""
    spec = _spec(synth_dir, fold_settings=SELECTION)
    written = _write_records(tmp_path, spec, [_key("B"), _key("D")])
    saved = read_json(written[_key("D").path()])
    saved["selection"]["per_fold"]["B"]["run.encoder.kernel"] = "5"
    write_json(written[_key("D").path()], saved)
    with pytest.raises(MixedSettings) as error:
        pool({path: read_run_record(tmp_path / path) for path in written}, tmp_path)
    assert (f"selection.per_fold.B.run.encoder.kernel 5 ({_key('B').path()}) / '5' "
            f"({_key('D').path()})") in str(error.value)


TINY = """
preset = "quick"
encoder = "{encoder}"
data_dir = "{data}"
test_users = ["B", "C"]
epochs = {epochs}
plots = "none"
{extra}
[[experiments]]
variants = ["A"]
annotations = ["original"]
"""
FOLD_SETTINGS = """
[fold_settings.B]
kernel = 5
lowpass = false
"""


@pytest.fixture(scope="module")
def grids(tmp_path_factory, synth_dir) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("nested")
    found = {}
    for name, epochs, extra in (("ed-tcn", 3, FOLD_SETTINGS), ("ms-tcn", 1, "")):
        text = TINY.format(encoder=name, data=synth_dir, epochs=epochs, extra=extra)
        if name == "ms-tcn":             # an MS-TCN epoch costs many of ED-TCN's: one, one fold
            text = text.replace('test_users = ["B", "C"]', 'test_users = ["B"]')
        else:                            # model A on the revised labels too: the side-by-side
            text += '\n[[experiments]]\nvariants = ["A"]\nannotations = ["revised"]\n'
        spec = root / f"{name}.toml"
        spec.write_text(text)
        assert grid_main(["--spec", str(spec), "--out", str(root / name), "--workers", "0"]) == 0
        found[name] = root / name
    return found


@pytest.mark.slow
def test_a_nested_selection_is_one_configuration_beside_other_architectures(grids, tmp_path,
                                                                             capsys):
    """Its folds' runs differ in kernel, low-pass filter and data fingerprint, yet pool as one
    configuration; beside MS-TCN on the same release its data counts at the common setting."""
    run = grids["ed-tcn"] / "runs/original/bidirectional/A-fixed/seed0"
    assert read_json(run / "B/config.json")["run"]["encoder"]["kernel"] == 5
    assert read_json(run / "C/config.json")["run"]["encoder"]["kernel"] == 10
    assert tables_main(["paper", str(grids["ed-tcn"]), "--no-figures", "--out",
                        str(tmp_path / "paper")]) == 0
    runs = pd.read_csv(tmp_path / "paper" / "runs.csv")
    assert len(runs[runs.annotations == "original"]) == 2
    assert tables_main(["architectures", str(grids["ed-tcn"]), str(grids["ms-tcn"]), "--out",
                        str(tmp_path / "side")]) == 0, capsys.readouterr().err
    caption = "kernel, lowpass chosen per outer fold on its training users alone (a nested"
    assert caption in (tmp_path / "paper" / "table2.tex").read_text()
    assert caption not in (tmp_path / "side" / "table2.tex").read_text().split("MS-TCN")[-1]
    side = pd.read_csv(tmp_path / "side" / "architectures.csv").set_index(["architecture",
                                                                             "model"])
    assert side.loc[("ED-TCN", "A"), "selection"].startswith(caption)
    assert side.loc[("MS-TCN", "A"), "selection"] != side.loc[("MS-TCN", "A"), "selection"]  # NaN
    assert caption in (tmp_path / "side" / "architectures.md").read_text()
    tex = (tmp_path / "side" / "architectures.tex").read_text()
    assert tex.count(caption) == 1 and f"ED-TCN: {caption}" in tex     # once, its own sentence


@pytest.mark.slow
def test_a_run_that_does_not_hold_its_folds_selected_settings_is_refused(grids, tmp_path,
                                                                         capsys):
    grid = tmp_path / "grid"
    shutil.copytree(grids["ed-tcn"], grid)
    config = grid / "runs/original/bidirectional/A-fixed/seed0/B/config.json"
    saved = read_json(config)
    saved["run"]["encoder"]["kernel"] = 7
    write_json(config, saved)
    capsys.readouterr()
    assert tables_main(["paper", str(grid), "--no-figures", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "A-fixed/seed0/B" in err and "run.encoder.kernel" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()
    (grid / "grid.json").unlink()          # runs without a grid's spec: the pooling rule's check
    assert tables_main(["runs", str(grid / "runs"), "--out",
                        str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "run.encoder.kernel 7, its selection's 5 on fold B" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_a_selection_is_never_stacked_and_is_shown_before_a_grid_runs(synth_dir, tmp_path,
                                                                      capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(TINY.format(encoder="ed-tcn", data=synth_dir, epochs=3, extra=FOLD_SETTINGS))
    assert grid_main(["--spec", str(spec), "--out", str(tmp_path / "g"), "--stack", "2"]) == 2
    assert "use --stack 1" in capsys.readouterr().err
    assert grid_main(["--spec", str(spec), "--out", str(tmp_path / "g"), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "settings per outer fold (a nested selection): B kernel 5, lowpass false" in out
