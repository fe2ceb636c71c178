"""Options that say what they do (issue 66): an empty or blank value of any option or argument of
every command is refused in one line, exit 2, before any work. ``--out ""`` was the current
folder (``Path("")`` is ``.``), ``--archive ""`` the same, ``--mlflow ""`` no tracking at all,
``--data-dir ""`` the default release."""
from __future__ import annotations

import argparse

import pytest

from baseline.cli import build_parser as baseline_parser
from jigsaws_tools.cli.main import build_parser as tools_parser
from multitask.evidence.cli import build_parser as tables_parser
from multitask.evidence.cli import main as tables_main
from multitask.grid.cli import build_parser as grid_parser
from multitask.inference.evaluate_cli import build_parser as evaluate_parser
from multitask.inference.export_cli import build_parser as export_parser
from multitask.inference.predict_cli import build_parser as predict_parser
from multitask.train_cli import build_parser as train_parser

PARSERS = {"jigsaws-tools": tools_parser, "baseline-train": baseline_parser,
           "multitask-train": train_parser, "multitask-grid": grid_parser,
           "multitask-tables": tables_parser, "multitask-predict": predict_parser,
           "multitask-evaluate": evaluate_parser, "multitask-export": export_parser}


def _commands() -> list[tuple[str, argparse.ArgumentParser]]:
    """Every (sub)command: its name and its parser."""
    found = []
    for name, build in PARSERS.items():
        parser = build()
        subcommands = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subcommands:
            found.append((name, parser))
        for action in subcommands:
            found += [(f"{name} {word}", sub) for word, sub in action.choices.items()]
    return found


def _valued(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The options and arguments of ``parser`` that take a value."""
    return [a for a in parser._actions if a.nargs != 0 and a.help != argparse.SUPPRESS
            and not isinstance(a, argparse._SubParsersAction) and a.dest != "help"]


def _argv(parser: argparse.ArgumentParser, action: argparse.Action, value: str) -> list[str]:
    """A command line giving ``action`` the value ``value`` first: its other values, if it
    takes several, and the positional arguments before it filled."""
    if not action.option_strings:
        before = [a for a in _valued(parser) if not a.option_strings]
        return ["x"] * before.index(action) + [value]
    count = action.nargs if isinstance(action.nargs, int) else 1
    return [action.option_strings[-1], value] + ["x"] * (count - 1)


@pytest.mark.parametrize("value", ["", "  "])
def test_every_option_refuses_an_empty_or_blank_value(capsys, value):
    checked = 0
    for name, parser in _commands():
        for action in _valued(parser):
            with pytest.raises(SystemExit) as stopped:
                parser.parse_args(_argv(parser, action, value))
            err = capsys.readouterr().err.strip().splitlines()[-1]
            shown = "/".join(action.option_strings) or action.metavar or action.dest
            assert stopped.value.code == 2, (name, shown)
            assert f"expected a value, got {value!r}" in err, (name, shown, err)
            checked += 1
    assert checked > 100                    # every command's path, URI, name and number options


@pytest.mark.parametrize("argv, shown", [(["paper", "grid", "--out", ""], "--out"),
                                         (["archive", "grid", ""], "DIR"),
                                         (["grid", "--out", ""], "--out"),        # old forms
                                         (["grid", "--archive", ""], "--archive")])
def test_an_empty_output_path_writes_nothing(tmp_path, monkeypatch, capsys, argv, shown):
    """``multitask-tables GRID --out ""`` wrote its tables into the current folder."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "grid").mkdir()
    with pytest.raises(SystemExit) as stopped:
        tables_main(argv)
    assert stopped.value.code == 2
    assert f"argument {shown}: expected a value, got ''" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grid"]
