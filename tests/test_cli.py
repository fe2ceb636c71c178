"""The eight commands: quick, quiet start, --version, help and default for every option,
range-checked values, deprecated spellings that still work, each warning printed once."""
from __future__ import annotations

import argparse
import ast
import importlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from jigsaws_tools.cli import arg_types
from jigsaws_tools.cli.common import (_TF_NOISE, Interrupted, configure_output, package_version,
                                      run_command)
from multitask.evidence.commands import STUDIES

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = {"jigsaws-tools": "jigsaws_tools.cli.main", "baseline-train": "baseline.cli",
            "multitask-train": "multitask.train_cli", "multitask-grid": "multitask.grid.cli",
            "multitask-tables": "multitask.evidence.cli",
            "multitask-predict": "multitask.inference.predict_cli",
            "multitask-evaluate": "multitask.inference.evaluate_cli",
            "multitask-export": "multitask.inference.export_cli"}
HEAVY = ("tensorflow", "scipy", "pandas", "matplotlib")
#: The lines TensorFlow, absl and oneDNN print: glog-style C++ lines, absl's banner, oneDNN's
#: notices, TensorFlow's Python warnings.
TF_LINE = re.compile(r"^[IWEF]\d{4} |absl::|oneDNN|^WARNING:tensorflow|To enable the following",
                     re.MULTILINE)


def _python(*args: str, **kwargs) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("TF_CPP_MIN_LOG_LEVEL", None)           # as a user's shell has it
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env,
                          timeout=600, **kwargs)


@pytest.mark.parametrize("module,args", [(m, ["--help"]) for m in COMMANDS.values()]
                         + [("multitask.train_cli", ["--variant", "Pc", "--help"]),
                            ("jigsaws_tools.cli.main", ["inspect", "--help"])])
def test_help_loads_no_heavy_module_and_prints_no_tensorflow_line(module, args):
    script = (f"import sys\nfrom {module} import main\ntry:\n    main({args!r})\n"
              f"except SystemExit:\n    pass\n"
              f"print('loaded:', [m for m in {HEAVY!r} if m in sys.modules])")
    result = _python("-c", script)
    assert result.returncode == 0, result.stderr
    assert "loaded: []" in result.stdout
    assert "usage:" in result.stdout
    assert not TF_LINE.search(result.stdout + result.stderr)


@pytest.mark.parametrize("prog,module", COMMANDS.items())
def test_version_on_every_command(prog, module):
    result = _python("-m", module, "--version")
    assert result.returncode == 0, result.stderr
    assert result.stdout == f"{prog} {package_version()}\n"


def _parsers() -> list[argparse.ArgumentParser]:
    parsers = []
    for name in COMMANDS.values():
        parser = importlib.import_module(name).build_parser()
        parsers.append(parser)
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
    return parsers


@pytest.mark.parametrize("parser", _parsers(), ids=lambda p: p.prog)
def test_every_option_has_help_and_shows_its_default(parser):
    formatter = parser._get_formatter()
    for action in parser._actions:
        if action.help == argparse.SUPPRESS or isinstance(action, argparse._SubParsersAction):
            continue
        assert action.help, f"{parser.prog} {action.option_strings or action.dest}: no help"
        shown = formatter._get_help_string(action)
        flag = action.nargs == 0
        states_default = ("default" in shown or "required" in shown or action.required
                          or not action.option_strings)
        assert flag or states_default, f"{parser.prog} {action.option_strings}: no default shown"


@pytest.mark.parametrize("module,args,message", [
    ("multitask.train_cli", ["--hidden", "0"], "--hidden: expected an integer >= 1, got '0'"),
    ("multitask.train_cli", ["--keep-prob", "0"], "--keep-prob: expected a number in (0, 1]"),
    ("multitask.train_cli", ["--momentum", "1"], "--momentum: expected a number in [0, 1)"),
    ("multitask.train_cli", ["--lr", "nan"], "--lr: expected a finite number > 0, got 'nan'"),
    ("multitask.train_cli", ["--alpha", "-1"], "--alpha: expected a finite number >= 0"),
    ("baseline.cli", ["--epochs", "0"], "--epochs: expected an integer >= 1, got '0'"),
    ("baseline.cli", ["--eval-at", "10,0"], "--eval-at: expected an integer >= 1, got '0'"),
    ("baseline.cli", ["--threads", "-1"], "--threads: expected an integer >= 0, got '-1'"),
    ("multitask.grid.cli", ["--workers", "-1"], "--workers: expected an integer >= 0, got '-1'"),
    ("multitask.grid.cli", ["--stack", "two"], "--stack: expected an integer >= 1, got 'two'"),
    ("multitask.inference.predict_cli", ["--threads", "-1"],
     "--threads: expected an integer >= 0, got '-1'"),
    ("multitask.inference.evaluate_cli", ["--checkpoint", "0"],
     "--checkpoint: expected an integer >= 1, got '0'"),
    ("multitask.inference.export_cli", ["--checkpoint", "last"],
     "--checkpoint: expected an integer >= 1, got 'last'"),
])
def test_out_of_range_values_are_argparse_errors_naming_the_range(module, args, message, capsys):
    with pytest.raises(SystemExit) as exit_:
        importlib.import_module(module).main(args + ["--out", "unused"])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("args,message", [
    (["--variant", "A", "--alpha", "1"], "--alpha is a GradNorm setting; add --weighting gradnorm"),
    (["--variant", "APc", "--weight-lr", "0.1"], "--weight-lr is a GradNorm setting"),
    (["--variant", "APc", "--ordinal-loss", "mean"],
     "--ordinal-loss applies to an ordered progress head (APoc, Poc), not to variant APc"),
])
def test_options_the_run_would_ignore_are_refused(args, message, tmp_path, capsys):
    from multitask.train_cli import main

    with pytest.raises(SystemExit) as exit_:
        main([*args, "--synthetic", "--out", str(tmp_path / "run")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"multitask-train: error: {message}")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("parse,good,bad", [
    (arg_types.positive_int, {"1": 1, "120": 120}, ["0", "-3", "1.5", "x", ""]),
    (arg_types.non_negative_int, {"0": 0, "7": 7}, ["-1", "2.0"]),
    (arg_types.probability, {"1": 1.0, "0.5": 0.5}, ["0", "1.01", "nan", "-0.2"]),
    (arg_types.momentum, {"0": 0.0, "0.9": 0.9}, ["1", "-0.1", "inf"]),
    (arg_types.positive_float, {"1e-3": 1e-3}, ["0", "-1", "inf", "nan"]),
    (arg_types.finite_float, {"-2.5": -2.5}, ["inf", "-inf", "nan", "one"]),
    (arg_types.positive_int_list, {"100,110, 120": (100, 110, 120), "5": (5,)},
     ["", "1,,2", "0,1", "a"]),
])
def test_range_checked_types(parse, good, bad):
    for text, value in good.items():
        assert parse(text) == value
    for text in bad:
        with pytest.raises(argparse.ArgumentTypeError, match="expected"):
            parse(text)


@pytest.mark.slow
def test_deprecated_spellings_still_work_and_say_so_once(synth_dir, tmp_path, capsys, caplog):
    from jigsaws_tools.cli.main import main as tools_main
    from multitask.grid.cli import main as grid_main

    assert tools_main(["synth", str(tmp_path / "s"), "--seed", "2"]) == 0
    err = capsys.readouterr().err
    assert "the positional DIR is deprecated; use --out DIR" in err
    assert err.count("--seed is deprecated; use --synthetic-seed") == 1
    assert (tmp_path / "s" / "meta_file_Suturing.txt").is_file()
    assert tools_main(["amendments", str(synth_dir), "--version", "original"]) == 0
    captured = capsys.readouterr()
    assert "0 amendments" in captured.out
    assert captured.err.count("deprecated") == 2
    assert "--version is deprecated; use --annotations" in captured.err
    spec = tmp_path / "old.toml"
    spec.write_text(f'data = "{synth_dir}"\nfolds = ["C"]\nhidden = 8\nepochs = 1\n'
                    '[[experiments]]\nvariants = ["A"]\n')
    assert grid_main(["--spec", str(spec), "--out", str(tmp_path / "g"), "--threads-per-job", "1",
                      "--dry-run"]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("--threads-per-job is deprecated; use --threads") == 1
    warnings = [r.getMessage() for r in caplog.records]
    assert sum("spec key 'data' is deprecated; use 'data_dir'" in w for w in warnings) == 1
    assert sum("spec key 'folds' is deprecated; use 'test_users'" in w for w in warnings) == 1
    assert "seed0/C" in captured.out and "1 runs" in captured.out


def _refused(main, argv: list[str], capsys) -> str:
    """The one line a command refuses ``argv`` with (exit 2, nothing on standard output)."""
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    captured = capsys.readouterr()
    assert exit_.value.code == 2
    assert captured.out == ""
    assert len(captured.err.splitlines()) == 1, captured.err
    return captured.err


@pytest.mark.parametrize("argv", [
    ["inspect", "--data-dir", "{given}", "{stray}"],
    ["stages", "{stray}", "--data-dir", "{given}"],
    ["synth", "--out", "{given}", "{stray}"],
])
def test_an_old_positional_folder_with_the_option_is_refused(argv, synth_dir, tmp_path, capsys):
    from jigsaws_tools.cli.main import main as tools_main

    given, stray = str(synth_dir), str(tmp_path / "stray")
    err = _refused(tools_main, [a.format(given=given, stray=stray) for a in argv], capsys)
    assert err.startswith(f"jigsaws-tools {argv[0]}: error: ")
    assert given in err and stray in err and "positional DIR" in err
    assert "deprecated" not in err
    assert not (tmp_path / "stray").exists()


def test_an_old_positional_folder_with_synthetic_is_refused(synth_dir, capsys):
    from jigsaws_tools.cli.main import main as tools_main

    err = _refused(tools_main, ["inspect", "--synthetic", str(synth_dir)], capsys)
    assert "--synthetic" in err and str(synth_dir) in err


@pytest.mark.parametrize("command, option", [
    *[(command, option) for command in ("inspect", "stages", "amendments", "plot")
      for option in (["--test-user", "B"], ["--test-user=B"])],
    ("amendments", ["--format", "own/my_robot.toml"]),      # the release's amendments only
    ("amendments", ["--format=own/my_robot.toml"]),
])
def test_an_option_a_subcommand_does_not_take_is_named(command, option, synth_dir, capsys):
    from jigsaws_tools.cli.main import main as tools_main

    err = _refused(tools_main, [command, "--data-dir", str(synth_dir), *option], capsys)
    name = option[0].split("=")[0]
    assert err.startswith(f"jigsaws-tools {command}: error: {command} takes no {name} option")
    assert "deprecated" not in err and "usage" not in err


def test_old_and_new_spec_keys_give_the_same_grid(synth_dir, tmp_path):
    from multitask.grid.spec import load_spec

    old, new = tmp_path / "old.toml", tmp_path / "new.toml"
    old.write_text(f'data = "{synth_dir}"\nfolds = ["C", "D"]\n')
    new.write_text(f'data_dir = "{synth_dir}"\ntest_users = ["C", "D"]\n')
    assert load_spec(old) == load_spec(new)
    both = tmp_path / "both.toml"
    both.write_text(f'data = "{synth_dir}"\ndata_dir = "{synth_dir}"\n')
    with pytest.raises(ValueError, match=r"both\.toml: both 'data' and 'data_dir'"):
        load_spec(both)


def test_tensorflow_start_up_lines_are_recognised():
    noise = ["WARNING: All log messages before absl::InitializeLog() is called are written to "
             "STDERR\n",
             "I0000 00:00:1795276466.592615    8348 port.cc:153] oneDNN custom operations on.\n",
             "E0000 00:00:1795276493.637004    8808 util.cc:131] oneDNN supports DT_BOOL only\n",
             "To enable the following instructions: AVX2 FMA, in other operations, rebuild\n"]
    kept = ["WARNING: Suturing_G001: transcription present but no kinematics; trial skipped\n",
            "/usr/lib/python3/site-packages/x.py:3: DeprecationWarning: old\n"]
    assert all(_TF_NOISE.match(line) for line in noise)
    assert not any(_TF_NOISE.match(line) for line in kept)


def test_verbose_shows_tensorflow_logs_and_default_respects_the_environment(monkeypatch):
    monkeypatch.delenv("TF_CPP_MIN_LOG_LEVEL", raising=False)
    configure_output(verbose=False)
    assert os.environ["TF_CPP_MIN_LOG_LEVEL"] == "3"
    monkeypatch.setenv("TF_CPP_MIN_LOG_LEVEL", "1")
    configure_output(verbose=False)
    assert os.environ["TF_CPP_MIN_LOG_LEVEL"] == "1"
    configure_output(verbose=True)
    assert os.environ["TF_CPP_MIN_LOG_LEVEL"] == "0"


@pytest.mark.slow
def test_training_prediction_and_export_print_no_tensorflow_line(synth_dir, tmp_path):
    result = _python("-m", "multitask.train_cli", "--data-dir", str(synth_dir), "--variant",
                     "APc", "--hidden", "8", "--epochs", "1", "--test-user", "C", "--no-plots",
                     "--out", str(tmp_path / "run"))
    assert result.returncode == 0, result.stderr
    assert "done: gesture: accuracy" in result.stdout
    assert not TF_LINE.search(result.stdout), result.stdout
    # only the build's own lines, on a first run of the default loops in this cache: the
    # announcement, then indented progress ("  still compiling (15 s)", "  built in 16 s")
    said = result.stderr.splitlines()
    if said:
        assert said[0].startswith("building the fused LSTM loops into "), said
        assert all(line.startswith("  ") for line in said[1:]), said
    recording = synth_dir / "kinematics" / "AllGestures" / "Suturing_C001.txt"
    result = _python("-m", "multitask.inference.predict_cli", str(tmp_path / "run"), str(recording),
                     "--no-plots", "--out", str(tmp_path / "labels"))
    assert result.returncode == 0, result.stderr
    assert "done: 1 recording(s)" in result.stdout
    assert not TF_LINE.search(result.stdout), result.stdout
    assert result.stderr == ""
    result = _python("-m", "multitask.inference.export_cli", str(tmp_path / "run"),
                     "--out", str(tmp_path / "exported"))
    assert result.returncode == 0, result.stderr
    assert "exported to" in result.stdout and result.stderr == ""


@pytest.mark.slow
def test_grid_prints_each_warning_once_and_logs_no_stray_message(synth_dir, tmp_path):
    release = shutil.copytree(synth_dir, tmp_path / "Suturing")
    (release / "kinematics" / "AllGestures" / "Suturing_B001.txt").unlink()
    spec = tmp_path / "spec.toml"
    spec.write_text(f'data_dir = "{release}"\ntest_users = ["C"]\nhidden = 8\nepochs = 1\n'
                    '[[experiments]]\nvariants = ["A"]\n')
    result = _python("-m", "multitask.grid.cli", "--spec", str(spec), "--out",
                     str(tmp_path / "grid"))
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if "Suturing_B001" in line]
    assert len(warnings) == 1 and "no kinematics" in warnings[0], result.stderr
    assert not TF_LINE.search(result.stdout + result.stderr)
    log = next((tmp_path / "grid").glob("runs/*/*/*/seed0/C/train.log")).read_text()
    assert warnings[0] in log
    assert "already finished" not in log


@pytest.mark.slow
def test_the_grid_s_own_process_never_imports_tensorflow(synth_dir, tmp_path):
    """The workers train; the grid's process plans, launches, watches and archives: after a dry
    run, a launch with one worker and its archive, TensorFlow is still not imported there (its
    import is about 5 CPU-s and half a gigabyte of memory)."""
    spec = tmp_path / "spec.toml"
    spec.write_text(f'data_dir = "{synth_dir}"\ntest_users = ["C"]\nhidden = 8\nepochs = 1\n'
                    'plots = "none"\n[[experiments]]\nvariants = ["A"]\n')
    command = ["--spec", str(spec), "--out", str(tmp_path / "grid")]
    script = ("import sys\nfrom multitask.grid.cli import main\n"
              f"for extra in ['--dry-run'], ['--workers', '1', '--archive', "
              f"{str(tmp_path / 'archive')!r}], ['--dry-run']:\n"
              f"    code = main({command!r} + extra)\n"
              "    print('exit', code, 'tensorflow' in sys.modules, flush=True)\n")
    result = _python("-c", script)
    said = [line for line in result.stdout.splitlines() if line.startswith("exit")]
    assert said == ["exit 0 False"] * 3, result.stdout + result.stderr
    assert "1 runs, 1 already finished, 0 to run" in result.stdout
    assert not TF_LINE.search(result.stdout + result.stderr)


@pytest.mark.slow
def test_dry_run_lists_only_the_runs_still_to_run(synth_dir, tmp_path, capsys):
    from multitask.grid.cli import main as grid_main

    spec = tmp_path / "spec.toml"
    spec.write_text(f'data_dir = "{synth_dir}"\ntest_users = ["C"]\nhidden = 8\nepochs = 1\n'
                    '[[experiments]]\nvariants = ["A"]\n')
    command = ["--spec", str(spec), "--out", str(tmp_path / "g"), "--threads", "1",
               "--workers", "0"]
    assert grid_main([*command, "--dry-run"]) == 0
    before = capsys.readouterr().out
    assert "runs/revised/bidirectional/A-fixed/seed0/C" in before
    assert "1 runs, 0 already finished, 1 to run" in before
    assert grid_main(command) == 0
    capsys.readouterr()
    assert grid_main([*command, "--dry-run"]) == 0
    after = capsys.readouterr().out
    assert "seed0/C" not in after and "1 runs, 1 already finished, 0 to run" in after


@pytest.mark.parametrize("module", ["multitask.train_cli", "baseline.cli"])
def test_a_missing_release_stops_before_any_output(tmp_path, capsys, module):
    main = importlib.import_module(module).main
    out = tmp_path / "ghost"
    assert main(["--data-dir", str(tmp_path / "nope"), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert "error: JIGSAWS Suturing folder not found" in captured.err
    assert captured.out == ""                            # no configuration header
    assert not out.exists()                              # no folder, no .lock left behind


@pytest.mark.parametrize("module", ["multitask.train_cli", "baseline.cli"])
def test_the_printed_configuration_is_short_lines_naming_the_format(synth_dir, tmp_path, capsys,
                                                                    monkeypatch, module):
    """The configuration header, printed before the data is read and TensorFlow loads (stopped
    right after it): the format's 76 column names summarised, not a 2,000-character line."""
    main = importlib.import_module(module).main

    def stop():
        raise ValueError("stopped before TensorFlow")
    monkeypatch.setattr("baseline.launch.import_tensorflow", stop)
    assert main(["--data-dir", str(synth_dir), "--out", str(tmp_path / "run")]) == 2
    lines = capsys.readouterr().out.splitlines()
    assert max(map(len, lines)) <= 220, max(lines, key=len)     # train's: 201 characters
    shown = [line for line in lines if line.startswith("data.recording_format: ")]
    assert len(shown) == 1 and shown[0].startswith(
        "data.recording_format: name=jigsaws, rate_hz=30.0, delimiter=whitespace, header=False, "
        "columns=76 (mtml_pos_x ... psm2_gripper)"), lines


def test_ctrl_c_exits_130_from_the_command_line_and_reaches_a_python_caller(capsys):
    """``run_command`` says one line: its own, or the ``Interrupted``'s (how to resume); then
    the process's own command line (``argv`` None) exits with 130, and Python code that passed
    its arguments gets the interrupt back, so that one Ctrl-C stops a test run."""
    def ctrl_c():
        raise KeyboardInterrupt

    def worded():
        raise Interrupted("x: interrupted; run it again to resume")

    assert run_command("x", False, ctrl_c) == 130
    with pytest.raises(KeyboardInterrupt):
        run_command("x", False, ctrl_c, argv=[])
    with pytest.raises(KeyboardInterrupt):
        run_command("x", False, worded, argv=["--out", "y"])
    assert capsys.readouterr().err == ("x: interrupted\nx: interrupted\n"
                                       "x: interrupted; run it again to resume\n")


@pytest.mark.parametrize("module", sorted(set(COMMANDS.values())))
def test_every_command_passes_its_arguments_to_run_command(module):
    """So that Ctrl-C reaches a Python caller of ``main(argv)`` (above): every call of
    ``run_command`` in a command's module passes ``argv=argv``."""
    path = ROOT / (module.replace(".", "/") + ".py")
    calls = [node for node in ast.walk(ast.parse(path.read_text()))
             if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "run_command"]
    assert calls and all(any(k.arg == "argv" and getattr(k.value, "id", "") == "argv"
                             for k in call.keywords) for call in calls), module


def test_the_tables_help_lists_every_study_on_one_screen():
    """``multitask-tables --help``: every study on a line of its own, in at most 40 lines of at
    most 80 characters (a terminal's default width)."""
    from multitask.evidence.cli import build_parser

    shown = build_parser().format_help().splitlines()
    assert len(shown) <= 40, f"{len(shown)} lines"
    assert not [line for line in shown if len(line) > 80]
    for study in STUDIES:
        assert any(re.match(rf"^  {study}\s{{2,}}\S", line) for line in shown), study


@pytest.mark.parametrize("study", sorted(STUDIES))
def test_every_study_s_help_shows_an_example_of_it(study):
    """Each ``multitask-tables STUDY --help`` holds an indented example command of that study."""
    from multitask.evidence.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    shown = sub.choices[study].format_help()
    assert re.search(rf"^    multitask-tables {study} \S", shown, re.M), shown
