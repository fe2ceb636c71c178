"""Mistakes caught at once (issue #48): a command checks its arguments (input files, the test
user among the release's, output folders free) before TensorFlow loads or data is read; a
misspelt option gets "did you mean"; a training's first line names the model with its weighting;
data warnings are said once per command, through logging with their level; help has no markup."""
from __future__ import annotations

import importlib
import json
import shutil

import pytest

from baseline.config import RunConfig
from jigsaws_tools.dataset import DataConfig
from rnn_seg.runs.folder import to_jsonable

from test_cli import COMMANDS, _python

#: Prints a command's exit code and whether TensorFlow was imported.
_CHECKED = ("import sys\nfrom {module} import main\ncode = main({argv!r})\n"
            "print('tensorflow loaded:', 'tensorflow' in sys.modules)\nsys.exit(code)")


def _run_checked(module: str, argv: list[str]):
    return _python("-c", _CHECKED.format(module=module, argv=argv))


@pytest.fixture
def run_record(synth_dir, tmp_path):
    """A run folder as far as the early checks read it: its config.json only."""
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    config = RunConfig(DataConfig(str(synth_dir)), test_user="B")
    (run_dir / "config.json").write_text(json.dumps(to_jsonable({"run": config})))
    return run_dir


def _refused_before_tensorflow(result, *expected: str) -> None:
    assert result.returncode == 2, result.stderr
    assert "tensorflow loaded: False" in result.stdout, result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert all(e in lines[0] for e in expected), lines[0]


@pytest.mark.parametrize("module", ["multitask.train_cli", "baseline.cli"])
def test_training_refuses_an_unknown_test_user_before_tensorflow(synth_dir, tmp_path, module):
    result = _run_checked(module, ["--data-dir", str(synth_dir), "--test-user", "A",
                                   "--out", str(tmp_path / "run")])
    _refused_before_tensorflow(result, "unknown test user 'A' (--test-user)",
                               "Suturing trials of users B, C")
    assert "model:" not in result.stdout and not (tmp_path / "run").exists()


def test_training_refuses_an_output_that_is_a_file_before_tensorflow(synth_dir, tmp_path):
    (tmp_path / "taken").write_text("mine")
    result = _run_checked("multitask.train_cli", ["--data-dir", str(synth_dir),
                                                  "--out", str(tmp_path / "taken")])
    _refused_before_tensorflow(result, "is a file")


def test_predict_refuses_a_missing_input_before_tensorflow(run_record, tmp_path):
    result = _run_checked("multitask.inference.predict_cli",
                          [str(run_record), str(tmp_path / "nope.txt"), "--out",
                           str(tmp_path / "labels")])
    _refused_before_tensorflow(result, "nope.txt: no such file or folder")


def test_export_refuses_an_existing_folder_before_tensorflow(run_record, tmp_path):
    (tmp_path / "saved").mkdir()
    (tmp_path / "saved" / "notes.txt").write_text("mine")
    result = _run_checked("multitask.inference.export_cli",
                          [str(run_record), "--out", str(tmp_path / "saved")])
    _refused_before_tensorflow(result, str(tmp_path / "saved"))
    assert (tmp_path / "saved" / "notes.txt").read_text() == "mine"


def test_evaluate_refuses_an_unknown_user_before_tensorflow(run_record, tmp_path):
    result = _run_checked("multitask.inference.evaluate_cli",
                          [str(run_record), "--test-user", "Z", "--out", str(tmp_path / "s")])
    _refused_before_tensorflow(result, "unknown test user 'Z'")


@pytest.mark.parametrize("module, argv, suggestion", [
    ("multitask.train_cli", ["--hiden", "64", "--out", "x"], "did you mean --hidden?"),
    ("multitask.train_cli", ["--weigthing=gradnorm", "--out", "x"], "did you mean --weighting?"),
    # the misspelling is named, not the required option it left out
    ("multitask.train_cli", ["--ouut", "x"], "did you mean --out?"),
    ("multitask.train_cli", ["--hiden", "64"], "did you mean --hidden?"),
    ("jigsaws_tools.cli.main", ["inspect", "--synthtic"], "did you mean --synthetic?"),
    ("multitask.inference.predict_cli", ["run", "x.txt", "--out", "o", "--no-plts"],
     "did you mean --no-plots?"),
])
def test_a_misspelt_option_gets_the_closest_one(module, argv, suggestion, capsys):
    with pytest.raises(SystemExit) as stop:
        importlib.import_module(module).main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert suggestion in err and len(err.splitlines()) == 1, err


def test_a_missing_required_option_without_a_misspelling_is_argparse_s_message(capsys):
    """An abbreviation argparse accepts is no misspelling: the missing --out is named."""
    with pytest.raises(SystemExit) as stop:
        importlib.import_module("multitask.train_cli").main(["--hid", "64"])
    assert stop.value.code == 2
    assert "the following arguments are required: --out" in capsys.readouterr().err


@pytest.mark.parametrize("module, argv, suggestion", [
    ("multitask.train_cli", ["--variant", "apoc", "--out", "x"], "did you mean APoc?"),
    ("multitask.train_cli", ["--weighting", "gradnrom", "--out", "x"], "did you mean gradnorm?"),
    ("jigsaws_tools.cli.main", ["inpsect"], "did you mean inspect?"),
])
def test_a_misspelt_choice_gets_the_closest_one(module, argv, suggestion, capsys):
    with pytest.raises(SystemExit) as stop:
        importlib.import_module(module).main(argv)
    assert stop.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "invalid choice" in last and last.endswith(suggestion), last
    assert last.split(":")[0] in ("multitask-train", "jigsaws-tools"), last


def test_an_option_like_none_gets_no_suggestion(capsys):
    with pytest.raises(SystemExit):
        importlib.import_module("multitask.train_cli").main(["--zzzzzz", "--out", "x"])
    err = capsys.readouterr().err
    assert "takes no --zzzzzz option" in err and "did you mean" not in err


@pytest.mark.parametrize("argv, first", [
    (["--variant", "APoc"], "model: APoc (gestures + progress by ordered classification), fixed "
                            "task weights w1 = w2 = 1 (the default; --weighting gradnorm for the "
                            "paper's GradNorm)"),
    (["--variant", "APoc", "--weighting", "fixed"], "model: APoc (gestures + progress by ordered "
                                                    "classification), fixed task weights w1 = w2 "
                                                    "= 1"),
    (["--variant", "APr", "--weighting", "gradnorm", "--alpha", "0.5"],
     "model: APr (gestures + progress by regression), GradNorm task weights (alpha 0.5"),
    (["--variant", "Pc"], "model: Pc (progress only, by classification)"),
])
def test_the_first_line_of_a_training_names_the_model_and_its_weighting(
        synth_dir, tmp_path, capsys, monkeypatch, argv, first):
    def stop():
        raise ValueError("stopped before TensorFlow")
    monkeypatch.setattr("baseline.launch.import_tensorflow", stop)
    from multitask.train_cli import main

    assert main([*argv, "--data-dir", str(synth_dir), "--out", str(tmp_path / "run")]) == 2
    line = capsys.readouterr().out.splitlines()[0]
    assert line.startswith(first), line
    assert line == first or "GradNorm task weights" in first


@pytest.fixture
def incomplete_release(synth_dir, tmp_path):
    release = shutil.copytree(synth_dir, tmp_path / "Suturing")
    (release / "kinematics" / "AllGestures" / "Suturing_B001.txt").unlink()
    return release


@pytest.mark.slow
def test_a_training_says_each_data_warning_once_with_its_level(incomplete_release, tmp_path):
    result = _python("-m", "multitask.train_cli", "--data-dir", str(incomplete_release),
                     "--test-user", "C", "--variant", "A", "--hidden", "4", "--epochs", "1",
                     "--no-plots", "--threads", "1", "--out", str(tmp_path / "run"))
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stderr.splitlines() if "Suturing_B001" in line]
    assert lines == ["WARNING: Suturing_B001: no kinematics; trial skipped"], result.stderr
    assert result.stdout.startswith("model: A (gestures only)")


@pytest.mark.slow
def test_the_python_api_says_a_data_warning_once_with_its_level(incomplete_release):
    script = ("from jigsaws_tools.dataset import DataConfig, load_dataset\n"
              f"config = DataConfig({str(incomplete_release)!r})\n"
              "load_dataset(config, use_cache=False)\nload_dataset(config, use_cache=False)\n")
    result = _python("-c", script)
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stderr.splitlines() if "Suturing_B001" in line]
    assert lines == ["WARNING: Suturing_B001: no kinematics; trial skipped"], result.stderr


def test_the_python_api_leaves_warnings_to_a_configured_logging(incomplete_release):
    script = ("import logging\nlogging.basicConfig(format='[%(name)s] %(message)s')\n"
              "from jigsaws_tools.dataset import DataConfig, load_dataset\n"
              f"load_dataset(DataConfig({str(incomplete_release)!r}), use_cache=False)\n")
    result = _python("-c", script)
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stderr.splitlines() if "Suturing_B001" in line]
    assert lines == ["[jigsaws_tools.release] Suturing_B001: no kinematics; trial skipped"]


@pytest.mark.parametrize("module, argv", [(m, ["--help"]) for m in COMMANDS.values()]
                         + [("jigsaws_tools.cli.main", [c, "--help"])
                            for c in ("synth", "inspect", "stages", "amendments", "plot")])
def test_help_has_no_rest_markup(module, argv, capsys):
    with pytest.raises(SystemExit):
        importlib.import_module(module).main(argv)
    text = capsys.readouterr().out
    assert "usage:" in text
    assert "``" not in text and ":func:`" not in text and "::\n" not in text, text
